"""The servicer flown through its FMU's thrusters, wheels and arm servos in
FMPy, against MuJoCo: `python scripts/thruster_demo.py` (see
python/nudyn_servicer/demo.py; `bash scripts/thruster-demo.sh` sets up first)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python"))

from nudyn_servicer.demo import main  # noqa: E402

sys.exit(main())
