#!/usr/bin/env python3
"""The emulator against a client nobody here wrote: ur_rtde's RTDEReceiveInterface.

Starts `robot-bridge emulate` on RTDE port 30004 (ur_rtde has no port option),
reads actual_q with ur_rtde and checks it is the emulator's home pose.
Needs the `ur-rtde` wheel from PyPI; skips, saying why, when it cannot be had
or the port is taken. Usage: python3 robot-bridge/tests/ur_rtde_check.py BINARY
"""
import math
import pathlib
import socket
import subprocess
import sys
import tempfile
import time

HOME = [0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0]


def skip(reason: str) -> int:
    print(f"ur_rtde check skipped: {reason}")
    return 0


def main() -> int:
    binary = pathlib.Path(sys.argv[1])
    target = tempfile.mkdtemp(prefix="ur_rtde_")
    install = subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--disable-pip-version-check", "--target", target, "ur-rtde==1.6.5"],
        capture_output=True,
        text=True,
    )
    if install.returncode != 0:
        return skip(f"pip could not install ur-rtde: {install.stderr.strip()[-300:]}")
    sys.path.insert(0, target)
    try:
        import rtde_receive  # noqa: PLC0415
    except ImportError as e:
        return skip(f"ur-rtde does not import here: {e}")
    with socket.socket() as probe:
        if probe.connect_ex(("127.0.0.1", 30004)) == 0:
            return skip("port 30004 is already taken")
    emulator = subprocess.Popen([str(binary), "emulate", "--rtde-port", "30004", "--script-port", "0", "--dashboard-port", "0", "--gripper-port", "0"], stdout=subprocess.PIPE, text=True)
    try:
        ready = emulator.stdout.readline()
        if "RTDE on" not in ready:
            print(f"ur_rtde check: 0 passed, 1 failed (emulator did not start: {ready!r})")
            return 1
        receiver = rtde_receive.RTDEReceiveInterface("127.0.0.1", 125.0, ["actual_q"])
        time.sleep(0.3)
        q = receiver.getActualQ()
        receiver.disconnect()
        ok = len(q) == 6 and all(abs(a - b) < 1e-9 for a, b in zip(q, HOME))
        print(f"ur_rtde read actual_q = {q}")
        print(f"ur_rtde check: {int(ok)} passed, {int(not ok)} failed")
        return 0 if ok else 1
    finally:
        emulator.terminate()
        emulator.wait(timeout=5)


if __name__ == "__main__":
    sys.exit(main())
