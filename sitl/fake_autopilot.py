#!/usr/bin/env python3
"""Fake PX4 / ArduPilot autopilot for Kestrel end-to-end tests. See sitl/README.md."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from fakeap.app import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
