#!/usr/bin/env python3
"""Validate nudyn's FMU of an MJCF file against MuJoCo; see
python/nudyn_validation/cli.py, or run with --help.

    .venv/bin/python scripts/validate.py examples/bus_arm7.xml [--out DIR]
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python"))

from nudyn_validation.cli import main  # noqa: E402  (needs the path above)

sys.exit(main())
