#!/usr/bin/env bash
# The physics referee (referee/): clear-the-table in MuJoCo with robosuite's
# UR5e + Robotiq 2F-140, objects nobody trained on, the running planner called
# over gRPC and its grasps executed by the robot-bridge's own kinematics.
#
#   scripts/referee.sh --server HOST:PORT --suite quick|standard|full \
#       --camera topdown|angled|random|all --out DIR [--pools test-a,test-b]
#
# Writes DIR/referee.json, DIR/referee.md and DIR/failures/*.png
# (`scripts/referee.sh --help` lists every option). Installs its Python
# dependencies into target/pydeps-referee, fetches the robot and object
# assets from the robosuite and pybullet wheels into target/referee-assets,
# and renders depth headless through OSMesa (MUJOCO_GL=egl on a GPU machine).
# MVGRASP_ROBOT_BRIDGE names a built robot-bridge binary (default: a release
# build made here). `scripts/referee.sh --self-check` runs the referee's own
# checks instead (referee/tests: kinematics, gripper, camera, oracle, seeds).
set -euo pipefail
cd "$(dirname "$0")/.."
deps=target/pydeps-referee
if ! PYTHONPATH="$deps" python3 -c "import mujoco, coacd, trimesh, scipy, PIL, grpc, grpc_tools, OpenGL" >/dev/null 2>&1; then
    echo "== installing the referee's Python dependencies into $deps" >&2
    python3 -m pip install --quiet --disable-pip-version-check --target "$deps" -r referee/requirements.txt >&2
fi
export MUJOCO_GL="${MUJOCO_GL:-osmesa}"
if [[ "$MUJOCO_GL" == osmesa ]]; then
    export PYOPENGL_PLATFORM=osmesa
    if ! ldconfig -p | grep -q 'libOSMesa\.so'; then
        if [[ $(id -u) -eq 0 ]] && command -v apt-get >/dev/null; then
            echo "== installing libosmesa6 (headless OpenGL for depth rendering)" >&2
            apt-get update -qq >&2 && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libosmesa6 >&2
        else
            echo "error: libOSMesa is missing: apt-get install libosmesa6 (or set MUJOCO_GL=egl on a GPU machine)" >&2
            exit 1
        fi
    fi
fi
bridge="${MVGRASP_ROBOT_BRIDGE:-}"
if [[ -z "$bridge" ]]; then
    cargo build --release --quiet -p mvgrasp-robot-bridge --bin robot-bridge
    bridge=target/release/robot-bridge
fi
if [[ "${1:-}" == --self-check ]]; then
    exec env PYTHONPATH="$deps:referee" MVGRASP_ROBOT_BRIDGE="$bridge" python3 -m unittest discover -s referee/tests -v
fi
exec env PYTHONPATH="$deps:referee" python3 -m mvgrasp_referee --bridge "$bridge" "$@"
