"""MuJoCo-side tools of nudyn: the reference quantities computed from MuJoCo
alone (`mujoco_reference`), the validation of an exported FMU against
MuJoCo's simulation of the same MJCF file (`scripts/validate.py`), judged
against MuJoCo's own sensitivity (`judgement`), and the same for every model
under a directory (`corpus`, `--corpus DIR`); and the converter of a
structural solver's modes (CalculiX) to nudyn's modal data file
(`calculix`, docs/flexible.md)."""
