#!/usr/bin/env python3
"""Fake PX4 / ArduPilot autopilot for Kestrel end-to-end tests. See sitl/README.md."""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

try:
    import pymavlink  # noqa: F401
except ImportError:
    venv_python = os.path.join(HERE, ".venv", "bin", "python")
    in_venv = os.path.realpath(sys.prefix) == os.path.realpath(os.path.join(HERE, ".venv"))
    if os.path.exists(venv_python) and not in_venv:
        os.execv(venv_python, [venv_python] + sys.argv)  # run with sitl/.venv (bash sitl/setup.sh)
    sys.exit("pymavlink is not installed: run `bash sitl/setup.sh` and use sitl/.venv/bin/python")

from fakeap.app import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
