#!/usr/bin/env python3
"""The monitoring as code, checked against the real thing (standard library only).

    python3 deploy/check_monitoring.py SERVER_BINARY CLIENT_BINARY

1. Starts mvgrasp-server (analytic backend) with its metrics port, loads it
   with `mvgrasp bench`, and checks that every metric the Grafana dashboard
   (deploy/grafana/mvgrasp.json) names is exported on the live /metrics, and
   every recording rule it names is defined in deploy/prometheus/rules.yml.
2. Starts a real Prometheus (Debian's package) scraping that server every
   second with the rules loaded, then asks its HTTP API for the series, for a
   rate computed from them, for the recording rules, and for every dashboard
   query: each must evaluate without error and return data.
Exit status 0 when every check passes.
"""

import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
import urllib.request

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..")
DASHBOARD = os.path.join(HERE, "grafana", "mvgrasp.json")
RULES = os.path.join(HERE, "prometheus", "rules.yml")
# Series Prometheus makes itself, not the server.
PROMETHEUS_OWN = {"up"}

failures = []


def check(name, ok, detail=""):
    print(f"{'ok  ' if ok else 'FAIL'} {name}{': ' + detail if detail and not ok else ''}")
    if not ok:
        failures.append(name)


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def get(url, timeout=5):
    with urllib.request.urlopen(url, timeout=timeout) as r:
        return r.read().decode()


def wait_for(url, seconds, what):
    deadline = time.monotonic() + seconds
    while True:
        try:
            return get(url)
        except OSError:
            if time.monotonic() > deadline:
                raise RuntimeError(f"{what} did not answer at {url} within {seconds} s") from None
            time.sleep(0.2)


def dashboard_queries():
    """(panel title, PromQL) for every target of the dashboard."""
    with open(DASHBOARD) as f:
        dashboard = json.load(f)
    return [(p["title"], t["expr"]) for p in dashboard["panels"] for t in p.get("targets", [])]


def names_in(expr):
    """Metric and recording-rule names a PromQL expression reads."""
    # Drop label matchers and strings first: label values are not names.
    bare = re.sub(r"\{[^}]*\}", "", re.sub(r'"[^"]*"', "", expr))
    return set(re.findall(r"\b(mvgrasp[_:][a-zA-Z0-9_:]+|up)\b", bare))


def exported_families(page):
    return set(re.findall(r"^# TYPE (\S+) ", page, re.M))


def base_family(name, families):
    """`name`'s family on the page (histogram series end in _bucket/_sum/_count)."""
    if name in families:
        return name
    for suffix in ("_bucket", "_sum", "_count"):
        if name.endswith(suffix) and name[: -len(suffix)] in families:
            return name[: -len(suffix)]
    return None


def query(prometheus, expr):
    url = f"{prometheus}/api/v1/query?" + urllib.parse.urlencode({"query": expr})
    try:
        answer = json.loads(get(url))
    except urllib.error.HTTPError as e:
        answer = json.loads(e.read().decode())
    return answer


def main():
    server_bin, client_bin = sys.argv[1], sys.argv[2]
    for tool in ("prometheus", "promtool"):
        if not shutil.which(tool):
            sys.exit(f"{tool} is missing: apt-get install prometheus (scripts/test.sh does)")
    work = tempfile.mkdtemp(prefix="mvgrasp-monitoring-")
    grpc_port, metrics_port, prom_port = free_port(), free_port(), free_port()
    procs = []
    try:
        server = subprocess.Popen(
            [server_bin, "--backend", "baseline", "--listen", f"127.0.0.1:{grpc_port}",
             "--metrics-listen", f"127.0.0.1:{metrics_port}"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        procs.append(server)
        metrics_url = f"http://127.0.0.1:{metrics_port}/metrics"
        wait_for(metrics_url, 60, "the server's metrics")

        config = os.path.join(work, "prometheus.yml")
        with open(config, "w") as f:
            f.write(
                "global: {scrape_interval: 1s, evaluation_interval: 1s}\n"
                f"rule_files: [{json.dumps(os.path.abspath(RULES))}]\n"
                "scrape_configs:\n"
                "  - job_name: mvgrasp\n"
                f"    static_configs: [{{targets: ['127.0.0.1:{metrics_port}']}}]\n")
        checked = subprocess.run(["promtool", "check", "config", config], capture_output=True, text=True)
        check("promtool check config (with the rules)", checked.returncode == 0, checked.stdout + checked.stderr)
        prometheus = f"http://127.0.0.1:{prom_port}"
        procs.append(subprocess.Popen(
            ["prometheus", f"--config.file={config}", f"--storage.tsdb.path={work}/data",
             f"--web.listen-address=127.0.0.1:{prom_port}"],
            stdout=subprocess.DEVNULL, stderr=open(os.path.join(work, "prometheus.log"), "w")))
        wait_for(f"{prometheus}/-/ready", 60, "Prometheus")

        # A small load: 4 callers for 12 s, one bad call (INVALID_ARGUMENT).
        bench = subprocess.run(
            [client_bin, "--server", f"http://127.0.0.1:{grpc_port}", "bench",
             "--depth", os.path.join(ROOT, "samples/table6/depth.png"),
             "--camera", os.path.join(ROOT, "samples/table6/camera.json"),
             "--concurrency", "4", "--duration-s", "12", "--warmup", "2", "--json"],
            capture_output=True, text=True)
        check("load: mvgrasp bench", bench.returncode == 0, bench.stderr[-2000:])
        report = json.loads(bench.stdout.strip().splitlines()[-1]) if bench.returncode == 0 else {}
        print(f"     load: {report.get('ok')} calls in {report.get('elapsed_s', 0):.1f} s, "
              f"{report.get('errors')} errors")

        page = get(metrics_url)
        families = exported_families(page)
        with open(RULES) as f:
            recorded = set(re.findall(r"^\s*- record: (\S+)", f.read(), re.M))
        queries = dashboard_queries()
        named = set().union(*(names_in(q) for _, q in queries))
        check("the dashboard names metrics", len(named) >= 15, str(sorted(named)))
        for name in sorted(named - PROMETHEUS_OWN):
            if ":" in name:
                check(f"recording rule {name} defined", name in recorded)
            else:
                check(f"metric {name} exported", base_family(name, families) is not None)

        # Give Prometheus a few scrapes and rule evaluations after the load.
        time.sleep(4)
        answer = query(prometheus, 'sum(mvgrasp_requests_total{method="PlanGrasps",code="Ok"})')
        result = answer.get("data", {}).get("result", [])
        scraped = float(result[0]["value"][1]) if result else 0.0
        check("Prometheus scraped the calls", scraped >= report.get("ok", 1), f"{scraped} against {report}")
        answer = query(prometheus, 'sum(rate(mvgrasp_requests_total{method="PlanGrasps"}[20s]))')
        result = answer.get("data", {}).get("result", [])
        rate = float(result[0]["value"][1]) if result else 0.0
        check("a rate from the scraped series", rate > 0, json.dumps(answer))
        print(f"     Prometheus: {scraped:.0f} PlanGrasps calls scraped, {rate:.1f} calls/s over the last 20 s")
        for name in sorted(recorded):
            result = query(prometheus, name).get("data", {}).get("result", [])
            check(f"recording rule {name} evaluated", bool(result))
        for title, expr in queries:
            instant = expr.replace("$__rate_interval", "20s")
            answer = query(prometheus, instant)
            result = answer.get("data", {}).get("result", [])
            check(f"dashboard query evaluates with data: {title}: {expr}",
                  answer.get("status") == "success" and bool(result), json.dumps(answer)[:500])
        alerts = json.loads(get(f"{prometheus}/api/v1/rules?type=alert"))["data"]["groups"]
        loaded = sorted(r["name"] for g in alerts for r in g["rules"])
        check("alerts loaded in Prometheus", len(loaded) >= 6, str(loaded))
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
        shutil.rmtree(work, ignore_errors=True)
    print(f"check_monitoring: {len(failures)} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
