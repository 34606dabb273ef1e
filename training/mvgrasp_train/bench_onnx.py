"""CPU time of grasp networks through onnxruntime, one intra-op thread.

    python3 -m mvgrasp_train.bench_onnx MODEL.onnx [MODEL.onnx ...] [--runs 50] [--level all ...]

Prints, per model (and graph optimisation level, `--level`: ONNX Runtime's
`all` by default, the server's), the median and 90th percentile of one call
at batch 1 and at batch 6. The input is a view-like image (a block of
surface on an empty background). Needs numpy and onnxruntime (the Python
binding of the library `ort` loads), not PyTorch.
"""

import argparse
import json
import time

import numpy as np
import onnxruntime


# ONNX Runtime's graph optimisation levels, by the names the CLI takes.
LEVELS = {name: getattr(onnxruntime.GraphOptimizationLevel, value) for name, value in (
    ("disable", "ORT_DISABLE_ALL"), ("basic", "ORT_ENABLE_BASIC"), ("extended", "ORT_ENABLE_EXTENDED"),
    ("layout", "ORT_ENABLE_LAYOUT"), ("all", "ORT_ENABLE_ALL"),
) if hasattr(onnxruntime.GraphOptimizationLevel, value)}


def time_model(path, runs, level="all"):
    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = 1
    options.inter_op_num_threads = 1
    options.graph_optimization_level = LEVELS[level]
    session = onnxruntime.InferenceSession(path, options, providers=["CPUExecutionProvider"])
    meta = session.get_modelmeta().custom_metadata_map
    size = int(meta["mvgrasp.input_size_px"])
    result = {"model": path, "level": level, "input_px": size, "version": meta.get("mvgrasp.model_version")}
    for batch in (1, 6):
        views = np.zeros((batch, 1, size, size), np.float32)
        views[:, :, size // 4: 3 * size // 4, size // 3: 2 * size // 3] = 0.6
        for _ in range(5):
            session.run(None, {"views": views})
        times = []
        for _ in range(runs):
            t = time.perf_counter()
            session.run(None, {"views": views})
            times.append(time.perf_counter() - t)
        result[f"batch{batch}_p50_ms"] = 1e3 * float(np.median(times))
        result[f"batch{batch}_p90_ms"] = 1e3 * float(np.percentile(times, 90))
    return result


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("models", nargs="+")
    p.add_argument("--runs", type=int, default=50)
    p.add_argument("--level", nargs="+", choices=sorted(LEVELS), default=["all"],
                   help="graph optimisation levels to time each model at")
    args = p.parse_args()
    for path in args.models:
        for level in args.level:
            print(json.dumps(time_model(path, args.runs, level)))


if __name__ == "__main__":
    main()
