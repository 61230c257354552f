"""MuJoCo-side tools of nudyn: the reference quantities computed from MuJoCo
alone (`mujoco_reference`), and the validation of an exported FMU against
MuJoCo's simulation of the same MJCF file (`scripts/validate.py`)."""
