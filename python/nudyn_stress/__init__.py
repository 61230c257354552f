"""nudyn's stress suite: the exported FMU driven through FMPy on vehicles
built to be hard (long runs, extreme mass ratios, 1000 bodies, stiffness,
near-singular inertia, fast spin, huge and non-finite inputs), with a
figure per case and a table of what was measured.  Run by
scripts/stress.py; tests/python/test_stress.py runs the short mode."""
