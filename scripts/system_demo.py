"""One system file, three runners: `nudyn system` writes the plant and the
controller of a vehicle as an .ssp, which libcosim, FMPy and nudyn's own
driver fly; writes docs/systems/nu.png (|ν| over time from each) and prints
each runner's distance to the driver's loop stepped as that runner steps.

    .venv/bin/python scripts/system_demo.py [OUT_DIR]   # default out/systems

Needs `cargo build --release --workspace` (the nudyn binary and the FMU library)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from nudyn_driver import ssp  # noqa: E402
from nudyn_driver.locations import nudyn_binary  # noqa: E402

SYSTEMS = {
    # A tumbling bus (0.5 and -0.3 rad/s) with its arm, rate feedback c1 = 2/s.
    "bus_arm7": ["--stop", "30", "--step", "0.05", "--set", "plant.nu[4]=0.5", "--set", "plant.nu[5]=-0.3",
                 "--set", "controller.c1=2"],
    # A fixed-base rig spinning its four joints at 0.5 rad/s, the default c1 = 5/s.
    "fixed_rig": ["--stop", "5", "--step", "0.01", "--set", "plant.nu=0.5"],
}


def main() -> int:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "out" / "systems"
    out.mkdir(parents=True, exist_ok=True)
    figure, axes = plt.subplots(1, len(SYSTEMS), figsize=(11, 4))
    for axis, (name, options) in zip(axes, SYSTEMS.items()):
        path = out / f"{name}.ssp"
        subprocess.run([str(nudyn_binary()), "system", str(ROOT / "examples" / f"{name}.xml"), "-o", str(path),
                        *options], check=True, capture_output=True)
        system = ssp.read(path)
        runs = [ssp.run_loop(system, "gauss-seidel"), ssp.run_libcosim(system)]
        runs.append(ssp.run_fmpy(system))
        print(f"{name}: |nu| from {np.linalg.norm(runs[0].nu[0]):.3g} at t = 0")
        steps = round(system.stop_time / system.step)
        for run in runs:
            speed = np.linalg.norm(run.nu, axis=1)
            line = f"  {run.master:>12}: |nu| at t = {system.stop_time:g} s: {speed[steps]:.3e}"
            if run.master != "gauss-seidel":
                # FMPy may take one step past the stop time (docs/systems.md): compare the common points.
                gap = np.abs(run.nu[: steps + 1] - ssp.run_loop(system, run.master).nu).max()
                line += f"; max |nu - driver loop stepped as {run.master}| = {gap:.1e} over {steps + 1} points"
            print(line)
            axis.semilogy(run.time, np.maximum(speed, 1e-300), label=run.master,
                          linestyle={"gauss-seidel": "-", "libcosim": "--", "fmpy": ":"}[run.master])
        axis.set_title(f"{name}.ssp")
        axis.set_xlabel("t (s)")
        axis.set_ylabel("|ν| (√J)")
        axis.set_ylim(bottom=1e-12)
        axis.legend()
    figure.tight_layout()
    target = ROOT / "docs" / "systems" / "nu.png"
    target.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(target, dpi=110)
    print(f"wrote {target.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
