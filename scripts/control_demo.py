"""Closed-loop demo of nudyn's controller FMU with its plant FMU, in FMPy and
libcosim: `python scripts/control_demo.py detumble|arm` (see
python/nudyn_control/demo.py; `bash scripts/control-demo.sh` sets up first)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python"))

from nudyn_control.demo import main  # noqa: E402

sys.exit(main())
