"""`python scripts/thruster_demo.py [--duration S] [--out DIR]`: the
servicer of examples/servicer.xml flown through its FMU's physical ports in
FMPy — the thrusters fired, a reaction wheel spun, the arm servoed — and the
same flight in MuJoCo, whose d.sensordata the FMU's sensordata must match.
Writes the plot and results.json; prints a summary. Exit status 0 when the
FMU and MuJoCo agree within 1e-6 (relative to max(1, |value|)), 1 if not.

The manoeuvre (ctrl by actuator name; ctrl[k] is MuJoCo's d.ctrl[k-1]):
  0–2 s     the four aft thrusters at full thrust (22 N): the bus accelerates
            along its +x axis (their sideways components cancel);
  2 s on    the arm servos to a new pose (shoulder pitch 0.5, elbow −1.2,
            wrist roll 1.0 rad): the bus recoils as the arm swings;
  3–3.25 s  a yaw couple: aft_mp, aft_mm, fore_pp, fore_pm (their forces
            cancel, their torques about the bus z axis add);
  4 s on    reaction wheel z driven at +0.2 N m: the reaction torque on the
            bus takes the yaw rate back out.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from nudyn_driver.cli import Nudyn  # noqa: E402
from nudyn_driver.instance import Instance  # noqa: E402
from nudyn_driver.locations import examples_dir, nudyn_binary, output_dir  # noqa: E402
from nudyn_driver.package import FmuPackage  # noqa: E402
from nudyn_validation.mujoco_run import MujocoVehicle  # noqa: E402

SERVICER = examples_dir() / "servicer.xml"
COMMUNICATION_STEP = 0.01
MUJOCO_SUBSTEPS = 10  # MuJoCo's RK4 at 1 ms
AGREEMENT = 1e-6
AFT = ["thr_aft_pp", "thr_aft_pm", "thr_aft_mp", "thr_aft_mm"]
YAW_COUPLE = ["thr_aft_mp", "thr_aft_mm", "thr_fore_pp", "thr_fore_pm"]
ARM_POSE = {"shoulder_pitch": 0.5, "elbow": -1.2, "wrist_roll": 1.0}


def manoeuvre(model: mujoco.MjModel):
    """ctrl(t): the controls held from communication point t."""
    index = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, k): k for k in range(model.nu)}

    def ctrl(t: float) -> np.ndarray:
        out = np.zeros(model.nu)
        if t < 2.0:
            out[[index[name] for name in AFT]] = 22.0
        if t >= 2.0:
            for name, angle in ARM_POSE.items():
                out[index[name]] = angle
        if 3.0 <= t < 3.25:
            out[[index[name] for name in YAW_COUPLE]] = 22.0
        if t >= 4.0:
            out[index["wheel_z"]] = 0.2
        return out

    return ctrl


@dataclass
class Flight:
    """The samples of one run at the communication points."""

    time: np.ndarray  # (n + 1,)
    ctrl: np.ndarray  # (n, nu): held over [t_k, t_k+1)
    fmu: np.ndarray  # (n + 1, nsensordata): the FMU's sensordata
    mujoco: np.ndarray  # (n + 1, nsensordata): MuJoCo's d.sensordata
    sensors: dict  # name -> slice of sensordata

    def sensor(self, name: str, side: str = "fmu") -> np.ndarray:
        return getattr(self, side)[:, self.sensors[name]]

    def disagreement(self) -> float:
        """max |fmu − mujoco| / max(1, |mujoco|) over every entry and time."""
        return float(np.max(np.abs(self.fmu - self.mujoco) / np.maximum(1.0, np.abs(self.mujoco))))


def sensor_slices(model: mujoco.MjModel) -> dict:
    return {
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SENSOR, i): slice(
            model.sensor_adr[i], model.sensor_adr[i] + model.sensor_dim[i]
        )
        for i in range(model.nsensor)
    }


def fly(fmu_path: Path, workdir: Path, duration: float) -> Flight:
    """The manoeuvre through the FMU (FMPy, one instance, doStep by
    doStep) and through MuJoCo, side by side."""
    package = FmuPackage.unzip(fmu_path, workdir / "servicer")
    mj = MujocoVehicle(SERVICER, COMMUNICATION_STEP / MUJOCO_SUBSTEPS)
    mj.set_state(mj.model.qpos0, np.zeros(mj.model.nv))
    ctrl_at = manoeuvre(mj.model)
    steps = round(duration / COMMUNICATION_STEP)
    held, fmu_samples, mj_samples = [], [], []
    zero_eps = np.zeros(mj.model.nv)
    with Instance(package, name="servicer", stop_time=duration) as plant:
        fmu_samples.append(plant.array("sensordata"))
        mj_samples.append(mj.data.sensordata.copy())
        for k in range(steps):
            ctrl = ctrl_at(k * COMMUNICATION_STEP)
            held.append(ctrl)
            plant.set_array("ctrl", ctrl)
            plant.step(COMMUNICATION_STEP, communication_point=k * COMMUNICATION_STEP)
            mj.advance(zero_eps, MUJOCO_SUBSTEPS, ctrl)
            fmu_samples.append(plant.array("sensordata"))
            mj_samples.append(mj.data.sensordata.copy())
    return Flight(
        time=COMMUNICATION_STEP * np.arange(steps + 1),
        ctrl=np.array(held),
        fmu=np.array(fmu_samples),
        mujoco=np.array(mj_samples),
        sensors=sensor_slices(mj.model),
    )


def plot(flight: Flight, model: mujoco.MjModel, path: Path) -> None:
    t, t_held = flight.time, flight.time[:-1]
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, k) for k in range(model.nu)]
    fig, axes = plt.subplots(5, 1, figsize=(9, 13), sharex=True)
    ax = axes[0]
    for k, name in enumerate(names[:8]):
        if np.any(flight.ctrl[:, k]):
            ax.step(t_held, flight.ctrl[:, k] + 0.4 * k, where="post", label=name)
    ax.set_ylabel("thrust (N, offset)")
    ax.set_title("servicer FMU: thrusters, wheel and arm driven through ctrl (FMPy)")
    ax.legend(fontsize=7, ncol=3)
    ax = axes[1]
    rates = flight.sensor("body_rates")
    for i, axis in enumerate("xyz"):
        ax.plot(t, rates[:, i], label=f"gyro {axis}")
    ax.plot(t, flight.sensor("body_rates", "mujoco")[:, 2], "k:", lw=1, label="MuJoCo gyro z")
    ax.set_ylabel("body rates (rad/s)")
    ax.legend(fontsize=7, ncol=4)
    ax = axes[2]
    for axis in "xyz":
        ax.plot(t, flight.sensor(f"wheel_{axis}_speed")[:, 0], label=f"wheel {axis}")
    ax.set_ylabel("wheel speed (rad/s)")
    ax.legend(fontsize=7)
    ax = axes[3]
    attitude = flight.sensor("attitude")
    for i, component in enumerate("wxyz"):
        ax.plot(t, attitude[:, i], label=f"q{component}")
    ax.set_ylabel("bus attitude")
    ax.legend(fontsize=7, ncol=4)
    ax = axes[4]
    bus, grasp = flight.sensor("bus_position"), flight.sensor("grasp_position")
    for i, axis in enumerate("xyz"):
        ax.plot(t, bus[:, i], label=f"bus {axis}")
        ax.plot(t, grasp[:, i], "--", label=f"grasp {axis}")
    ax.set_ylabel("position (m)")
    ax.set_xlabel("time (s)")
    ax.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def summary(flight: Flight) -> dict:
    def at(name: str, time: float) -> list[float]:
        k = int(round(time / COMMUNICATION_STEP))
        return flight.sensor(name)[min(k, len(flight.time) - 1)].tolist()

    end = float(flight.time[-1])
    return {
        "duration": end,
        "bus_position_end": at("bus_position", end),
        "body_rates_after_yaw_couple": at("body_rates", 3.5),
        "body_rates_end": at("body_rates", end),
        "wheel_z_speed_end": at("wheel_z_speed", end)[0],
        "max_sensordata_disagreement_with_mujoco": flight.disagreement(),
    }


def run(nudyn: Path, out: Path, duration: float) -> tuple[Flight, dict]:
    fmu = Nudyn(nudyn).export(SERVICER, out / "servicer.fmu")
    flight = fly(fmu, out, duration)
    model = mujoco.MjModel.from_xml_path(str(SERVICER))
    plot(flight, model, out / "servicer.png")
    result = summary(flight)
    (out / "results.json").write_text(json.dumps(result, indent=1) + "\n")
    return flight, result


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--duration", type=float, default=28.0, help="simulated seconds (default %(default)s)")
    p.add_argument("--out", type=Path, default=output_dir("thruster-demo"), help="output directory")
    p.add_argument("--nudyn", type=Path, default=nudyn_binary())
    args = p.parse_args(argv)
    _, result = run(args.nudyn, args.out, args.duration)
    for key, value in result.items():
        print(f"{key}: {value}")
    print(f"plot:    {args.out / 'servicer.png'}")
    print(f"numbers: {args.out / 'results.json'}")
    agreed = result["max_sensordata_disagreement_with_mujoco"] <= AGREEMENT
    print("FMU and MuJoCo agree" if agreed else f"FMU and MuJoCo DISAGREE beyond {AGREEMENT:g}")
    return 0 if agreed else 1


if __name__ == "__main__":
    sys.exit(main())
