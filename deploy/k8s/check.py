#!/usr/bin/env python3
"""Checks the Kubernetes manifests without a cluster (none runs here).

    PYTHONPATH=<kubernetes-validate, checkov, PyYAML> python3 deploy/k8s/check.py

For every overlay: `kubectl kustomize` renders it; kubernetes-validate
(offline schemas, --strict) accepts every object of Kubernetes 1.32 (the
ServiceMonitor CRD has no bundled schema: its wiring is checked below);
the objects fit together (Services and the PodDisruptionBudget select the
Deployment's pods, named ports exist, probes hit the gRPC port, the HPA
scales the Deployment, the ServiceMonitor finds the metrics port, the
ConfigMap is deploy/server.toml); checkov finds no failed check.
"""

import glob
import os
import subprocess
import sys
import tempfile

import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
KUBERNETES = "1.32.0"
failures = []


def check(name, ok, detail=""):
    print(f"{'ok  ' if ok else 'FAIL'} {name}{': ' + detail if detail and not ok else ''}")
    if not ok:
        failures.append(name)


def selects(selector, labels):
    return bool(selector) and all(labels.get(k) == v for k, v in selector.items())


def wiring(overlay, objects):
    by_kind = {}
    for o in objects:
        by_kind.setdefault(o["kind"], []).append(o)
    (deployment,) = by_kind["Deployment"]
    pod = deployment["spec"]["template"]
    pod_labels = pod["metadata"]["labels"]
    container = pod["spec"]["containers"][0]
    ports = {p["name"]: p["containerPort"] for p in container["ports"]}
    check(f"{overlay}: the Deployment's selector matches its pods",
          selects(deployment["spec"]["selector"]["matchLabels"], pod_labels))
    services = by_kind["Service"]
    for s in services:
        name = s["metadata"]["name"]
        check(f"{overlay}: Service {name} selects the planner pods", selects(s["spec"]["selector"], pod_labels))
        check(f"{overlay}: Service {name} targets named container ports",
              all(p["targetPort"] in ports for p in s["spec"]["ports"]), str(s["spec"]["ports"]))
    check(f"{overlay}: a headless Service for client-side balancing",
          any(s["spec"].get("clusterIP") == "None" for s in services))
    env = {e["name"]: e.get("value") for e in container.get("env", [])}
    secured = overlay.endswith("mtls")
    # Probes cannot speak TLS: with TLS they ask the plaintext health port.
    probed = "health" if secured else "grpc"
    for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
        check(f"{overlay}: {probe} is a gRPC health check on the {probed} port",
              container.get(probe, {}).get("grpc", {}).get("port") == ports.get(probed))
    if secured:
        mounted_at = {m["mountPath"]: m["name"] for m in container["volumeMounts"]}
        secrets = {v["name"]: v["secret"]["secretName"] for v in pod["spec"]["volumes"] if "secret" in v}
        files = [env.get(k) for k in ("MVGRASP_TLS_CERT", "MVGRASP_TLS_KEY", "MVGRASP_TLS_CLIENT_CA",
                                      "MVGRASP_BEARER_TOKEN_FILE")]
        check(f"{overlay}: TLS, client CA and token files come from mounted Secrets",
              all(f and mounted_at.get(os.path.dirname(f)) in secrets for f in files), f"{files} {secrets}")
        check(f"{overlay}: the health port is the one the server listens on",
              env.get("MVGRASP_HEALTH_LISTEN", "").endswith(f":{ports.get('health')}"))
    check(f"{overlay}: readiness asks for the planner service",
          container["readinessProbe"]["grpc"].get("service") == "mvgrasp.v1.GraspPlanner")
    security = container["securityContext"]
    check(f"{overlay}: non-root, read-only, no privilege escalation",
          pod["spec"]["securityContext"].get("runAsNonRoot") is True
          and security.get("readOnlyRootFilesystem") is True
          and security.get("allowPrivilegeEscalation") is False
          and security.get("capabilities", {}).get("drop") == ["ALL"])
    check(f"{overlay}: requests and limits set",
          all(k in container["resources"].get(side, {}) for side in ("requests", "limits") for k in ("cpu", "memory")))
    (hpa,) = by_kind["HorizontalPodAutoscaler"]
    check(f"{overlay}: the HPA scales the Deployment",
          hpa["spec"]["scaleTargetRef"]["name"] == deployment["metadata"]["name"])
    (pdb,) = by_kind["PodDisruptionBudget"]
    check(f"{overlay}: the PodDisruptionBudget selects the planner pods",
          selects(pdb["spec"]["selector"]["matchLabels"], pod_labels))
    (policy,) = by_kind["NetworkPolicy"]
    opened = {p["port"] for rule in policy["spec"]["ingress"] for p in rule["ports"]}
    check(f"{overlay}: the NetworkPolicy covers the planner pods and opens its ports",
          selects(policy["spec"]["podSelector"].get("matchLabels"), pod_labels) and opened == set(ports.values()),
          f"{opened} against {ports}")
    (monitor,) = by_kind["ServiceMonitor"]
    scraped = [s for s in services if selects(monitor["spec"]["selector"]["matchLabels"], s["metadata"]["labels"])]
    check(f"{overlay}: the ServiceMonitor selects one Service with its port",
          len(scraped) == 1 and all(e["port"] in {p["name"] for p in scraped[0]["spec"]["ports"]}
                                    for e in monitor["spec"]["endpoints"]),
          str([s["metadata"]["name"] for s in scraped]))
    (config,) = by_kind["ConfigMap"]
    with open(os.path.join(HERE, "..", "server.toml")) as f:
        check(f"{overlay}: the ConfigMap is deploy/server.toml", config["data"]["server.toml"] == f.read())
    mounted = [v["configMap"]["name"] for v in pod["spec"]["volumes"] if "configMap" in v]
    check(f"{overlay}: the pods mount the generated ConfigMap", mounted == [config["metadata"]["name"]])
    gpus = container["resources"].get("limits", {}).get("nvidia.com/gpu")
    if overlay == "gpu":
        check("gpu: one GPU per pod, the CUDA device, two sessions",
              gpus == "1" and env.get("MVGRASP_DEVICE") == "cuda" and env.get("MVGRASP_SESSIONS") == "2")
    else:
        check(f"{overlay}: no GPU asked for", gpus is None and "MVGRASP_DEVICE" not in env)
    metric = hpa["spec"]["metrics"][0]
    if overlay == "cpu-in-flight":
        check("cpu-in-flight: the HPA scales on calls in flight",
              metric["type"] == "Pods" and metric["pods"]["metric"]["name"] == "mvgrasp_in_flight_requests")
    else:
        check(f"{overlay}: the HPA scales on CPU", metric["type"] == "Resource" and metric["resource"]["name"] == "cpu")


def main():
    overlays = sorted(os.path.basename(d) for d in glob.glob(os.path.join(HERE, "overlays", "*")))
    check("overlays cpu, gpu, cpu-in-flight, cpu-mtls", {"cpu", "gpu", "cpu-in-flight", "cpu-mtls"} <= set(overlays),
          str(overlays))
    rendered_dir = tempfile.mkdtemp(prefix="mvgrasp-k8s-")
    for overlay in overlays:
        rendered = subprocess.run(["kubectl", "kustomize", os.path.join(HERE, "overlays", overlay)],
                                  capture_output=True, text=True)
        check(f"{overlay}: kubectl kustomize renders", rendered.returncode == 0, rendered.stderr)
        if rendered.returncode != 0:
            continue
        path = os.path.join(rendered_dir, f"{overlay}.yaml")
        with open(path, "w") as f:
            f.write(rendered.stdout)
        objects = [o for o in yaml.safe_load_all(rendered.stdout) if o]
        kinds = sorted(o["kind"] for o in objects)
        print(f"     {overlay}: {len(objects)} objects: {', '.join(kinds)}")
        validated = subprocess.run(
            [sys.executable, "-m", "kubernetes_validate", "--strict", "--quiet", "-k", KUBERNETES, path],
            capture_output=True, text=True)
        schema_less = [line for line in validated.stdout.splitlines() if "Couldn't find schema" in line]
        check(f"{overlay}: kubernetes-validate --strict ({KUBERNETES}) accepts every object",
              validated.returncode == 0 and all("ServiceMonitor" in line for line in schema_less),
              validated.stdout + validated.stderr)
        wiring(overlay, objects)
    scan = subprocess.run(
        [sys.executable, "-m", "checkov.main", "-d", rendered_dir, "--framework", "kubernetes",
         "--compact", "--quiet", "--skip-download", "--output", "json"],
        capture_output=True, text=True)
    try:
        report = yaml.safe_load(scan.stdout)
        summary = report["summary"] if isinstance(report, dict) else report[0]["summary"]
    except (yaml.YAMLError, KeyError, IndexError, TypeError):
        summary = None
    check("checkov: no failed check", summary is not None and summary["failed"] == 0,
          scan.stdout[-3000:] + scan.stderr[-1000:])
    if summary:
        print(f"     checkov: {summary['passed']} passed, {summary['failed']} failed, "
              f"{summary['skipped']} skipped (each skip carries its reason in the manifest)")
    print(f"k8s check: {len(failures)} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
