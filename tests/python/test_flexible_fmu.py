"""A vehicle with a flexible body as an FMU (docs/flexible.md; issue 49,
items 3 and 4): the modal coordinates are states and outputs after the
joints' in theta and nu, `modal_strain_energy` is an optional output, and
`nudyn describe` names each mode.

Fixture: tests/fixtures/flex/bench_vehicle.xml (a bus with a bench on a
hinge, its three modes in bench.json). The conservation case copies both
files with the modes' damping set to 0."""

from __future__ import annotations

import json
import shutil

import fmpy
import numpy as np
from conftest import ROOT

FIXTURES = ROOT / "tests" / "fixtures" / "flex"
# The bench's modes are theta[9..11] and nu[8..10] (1-based, as the FMU names them).
START = {"theta[9]": 0.05, "theta[10]": -0.02, "theta[11]": 0.01, "nu[4]": 0.1, "nu[7]": 0.3, "nu[8]": -0.2}


def undamped(tmp_path):
    shutil.copy(FIXTURES / "bench_vehicle.xml", tmp_path / "bench_vehicle.xml")
    modal = json.loads((FIXTURES / "bench.json").read_text())
    for mode in modal["modes"]:
        mode["damping_ratio"] = 0.0
    (tmp_path / "bench.json").write_text(json.dumps(modal))
    return tmp_path / "bench_vehicle.xml"


def test_describe_names_each_mode_after_the_joints(cli):
    description = json.loads(cli.run("describe", FIXTURES / "bench_vehicle.xml", "--json"))
    assert (description["nq"], description["nv"]) == (11, 10)
    modes = description["modes"]
    assert [m["name"] for m in modes] == ["bench:mode1", "bench:mode2", "bench:mode3"]
    assert [m["qpos_adr"] for m in modes] == [8, 9, 10] and [m["dof_adr"] for m in modes] == [7, 8, 9]
    # bench.json gives 1.5, 4 and 9 Hz.
    assert np.allclose([m["frequency"] for m in modes], [1.5, 4.0, 9.0], rtol=1e-12)
    text = cli.run("describe", FIXTURES / "bench_vehicle.xml")
    assert "bench:mode3, 9.000 Hz" in text


def test_the_modes_keep_the_mechanical_energy_in_co_simulation_and_model_exchange(cli, tmp_path):
    """Undamped, free-floating, eps = 0: K + modal_strain_energy stays what
    it was (dop853 at 1e-10 per second inside the FMU; CVODE at 1e-10 for
    model exchange), while strain energy and K exchange; the two interfaces
    agree within their tolerances."""
    model = undamped(tmp_path)
    fmu = cli.export(model, tmp_path / "bench.fmu", outputs=["kinetic_energy", "modal_strain_energy"])
    names = ["kinetic_energy", "modal_strain_energy"] + [f"theta[{k}]" for k in range(1, 12)]
    runs = {}
    for interface in ("CoSimulation", "ModelExchange"):
        runs[interface] = fmpy.simulate_fmu(
            fmu, fmi_type=interface, stop_time=3.0, output_interval=0.01, start_values={**START, "tolerance": 1e-10},
            relative_tolerance=1e-10, output=names,
        )
    cs = runs["CoSimulation"]
    energy = cs["kinetic_energy"] + cs["modal_strain_energy"]
    assert cs["modal_strain_energy"].max() - cs["modal_strain_energy"].min() > 0.1 * energy[0]
    drift = np.abs(energy - energy[0]).max() / energy[0]
    assert drift < 1e-8, drift
    me = runs["ModelExchange"]
    difference = max(np.abs(cs[n] - me[n]).max() for n in names[2:])
    assert difference < 1e-6, difference


def test_a_rigid_vehicle_reports_no_strain_energy(cli, tmp_path):
    fmu = cli.export(ROOT / "examples" / "bus_arm7.xml", tmp_path / "bus.fmu", outputs=["modal_strain_energy"])
    result = fmpy.simulate_fmu(fmu, stop_time=0.1, output=["modal_strain_energy"])
    assert np.all(result["modal_strain_energy"] == 0.0)


def test_the_coupled_frequencies_are_the_hybrid_coordinate_eigenproblems(cli, tmp_path):
    """Free-free, at rest, undamped: `nudyn linearize`'s frequencies of the
    bus, hinge and bench against the eigenproblem a GNC engineer builds from
    the modal data, K x = ω² M x with M = [[M_rr, M_rη], [M_rηᵀ, 1]]:
    M_rr MuJoCo's mass matrix of the rigid vehicle (the same MJCF),
    M_rη = J_ωᵀ L_r + J_vᵀ L_t from `nudyn modal`'s participation factors
    about the bench's frame and MuJoCo's Jacobian of that frame (body
    axes), K = diag(0, ω_k²)."""
    import mujoco

    model = undamped(tmp_path)
    linearized = json.loads(cli.run("linearize", model))
    coupled = sorted(e["frequency_hz"] for e in linearized["eigenvalues"] if e["imag"] > 0)

    rigid = mujoco.MjModel.from_xml_path(str(model))
    data = mujoco.MjData(rigid)
    mujoco.mj_forward(rigid, data)
    mass_rigid = np.zeros((rigid.nv, rigid.nv))
    mujoco.mj_fullM(rigid, data, mass_rigid)
    bench = rigid.body("bench").id
    jac_linear, jac_angular = np.zeros((3, rigid.nv)), np.zeros((3, rigid.nv))
    mujoco.mj_jac(rigid, data, jac_linear, jac_angular, data.xpos[bench], bench)
    to_body = data.xmat[bench].reshape(3, 3).T
    modal = json.loads(cli.run("modal", model.parent / "bench.json", "--json"))["modes"]
    coupling = np.column_stack([
        (to_body @ jac_angular).T @ m["participation"]["rotation"] + (to_body @ jac_linear).T @ m["participation"]["translation"]
        for m in modal
    ])
    m = len(modal)
    mass = np.block([[mass_rigid, coupling], [coupling.T, np.eye(m)]])
    stiffness = np.zeros_like(mass)
    stiffness[rigid.nv:, rigid.nv:] = np.diag([(2 * np.pi * mode["frequency"]) ** 2 for mode in modal])
    # K x = ω² M x as the symmetric L⁻¹ K L⁻ᵀ with M = L Lᵀ.
    factor_inverse = np.linalg.inv(np.linalg.cholesky(mass))
    squares = np.linalg.eigvalsh(factor_inverse @ stiffness @ factor_inverse.T)
    expected = sorted(np.sqrt(s) / (2 * np.pi) for s in squares if s > 1e-9)
    assert len(coupled) == len(expected) == m
    print("coupled", coupled, "relative difference", np.max(np.abs(np.subtract(coupled, expected)) / expected))
    assert np.allclose(coupled, expected, rtol=1e-9, atol=0), (coupled, expected)


def test_a_thruster_at_the_bench_tip_does_work_that_the_kinetic_and_strain_energy_gain(cli, tmp_path):
    """Actuators on sites at nodes (tests/fixtures/flex/bench_thruster.xml:
    a thruster at the bench's tip, a torquer at its middle; undamped, no
    gravity): the work of their forces, ∫ Σ actuatorfrc · actuatorvel dt,
    equals the gain of K + modal_strain_energy. Constant ctrl (a held input
    has no jump inside the run); the power, read at every 1 ms, integrated
    by Simpson's rule; dop853 at 1e-10 per second inside the FMU."""
    shutil.copy(FIXTURES / "bench_thruster.xml", tmp_path / "bench_thruster.xml")
    modal = json.loads((FIXTURES / "bench.json").read_text())
    for mode in modal["modes"]:
        mode["damping_ratio"] = 0.0
    (tmp_path / "bench.json").write_text(json.dumps(modal))
    fmu = cli.export(tmp_path / "bench_thruster.xml", tmp_path / "thruster.fmu",
                     outputs=["kinetic_energy", "modal_strain_energy"])
    stop, interval, ctrl = 2.0, 1e-3, (2.0, -0.5)
    signals = np.array([(0.0, *ctrl), (stop, *ctrl)],
                       dtype=[("time", np.float64), ("ctrl[1]", np.float64), ("ctrl[2]", np.float64)])
    # sensordata: thruster length, velocity, force; torquer velocity, force.
    names = ["kinetic_energy", "modal_strain_energy"] + [f"sensordata[{k}]" for k in range(1, 6)]
    result = fmpy.simulate_fmu(fmu, stop_time=stop, output_interval=interval, input=signals, output=names,
                               start_values={**START, "tolerance": 1e-10})
    assert np.allclose(result["sensordata[3]"], ctrl[0]) and np.allclose(result["sensordata[5]"], ctrl[1])
    power = result["sensordata[2]"] * result["sensordata[3]"] + result["sensordata[4]"] * result["sensordata[5]"]
    assert len(power) % 2 == 1, "Simpson's rule needs an even number of intervals"
    work = interval / 3 * (power[0] + power[-1] + 4 * power[1:-1:2].sum() + 2 * power[2:-1:2].sum())
    energy = result["kinetic_energy"] + result["modal_strain_energy"]
    gain = energy[-1] - energy[0]
    print(f"work {work:.12g} J, gain of K + strain energy {gain:.12g} J, difference {abs(work - gain):.2e} J, "
          f"largest energy {np.abs(energy).max():.6g} J")
    assert result["modal_strain_energy"].max() > 1e-3 * energy.max(), "the modes must take part"
    assert abs(gain) > 0.1 * energy[0], "the actuators must change the energy"
    # Measured 2.0e-9 J of a 4.30 J gain (largest energy 4.77 J).
    assert abs(work - gain) < 1e-8 * np.abs(energy).max(), (work, gain)
