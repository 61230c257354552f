"""Closed-loop co-simulation of a nudyn plant FMU with its controller FMU
(`nudyn export --controller`), in FMPy and in libcosim, and the checks of
the noninteracting control law: the Lyapunov function V = K + U against the
bound that sample-and-hold allows, detumbling to |nu| < 1e-6, and reaching a
target pose. Everything the checks compare against is computed from MuJoCo
(`reference.py`), not from nudyn."""
