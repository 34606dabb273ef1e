#!/usr/bin/env bash
# Puts ONNX Runtime's CPU library (from the PyPI wheel onnxruntime==1.31.1)
# at target/onnxruntime/libonnxruntime.so.1.31.1 and prints that path.
# The `ort` crate loads it at run time (load-dynamic); nothing else downloads
# a binary.
set -euo pipefail
cd "$(dirname "$0")/.."
version=1.31.1
dest=target/onnxruntime
lib="$dest/libonnxruntime.so.$version"
if [[ ! -s "$lib" ]]; then
    tmp=$(mktemp -d)
    trap 'rm -rf "$tmp"' EXIT
    echo "== fetching onnxruntime==$version from PyPI" >&2
    python3 -m pip download --quiet --no-deps --only-binary=:all: "onnxruntime==$version" -d "$tmp" >&2
    mkdir -p "$dest"
    python3 - "$tmp" "$dest" <<'PY'
import glob, os, shutil, sys, zipfile
tmp, dest = sys.argv[1], sys.argv[2]
wheel = glob.glob(os.path.join(tmp, "onnxruntime-*.whl"))[0]
with zipfile.ZipFile(wheel) as z:
    for name in z.namelist():
        if name.startswith("onnxruntime/capi/libonnxruntime.so"):
            with z.open(name) as src, open(os.path.join(dest, os.path.basename(name)), "wb") as out:
                shutil.copyfileobj(src, out)
PY
fi
realpath "$lib"
