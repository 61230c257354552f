"""`nudyn-validate --corpus DIR` (nudyn_validation.corpus) on a corpus of
our own (tests/fixtures/corpus: a model that exports and agrees, a scene
around it, a model that includes its arm, a refused one, one whose mesh
file is absent and one too stiff for the step), and the judgement of a
trajectory against MuJoCo's twin."""

from __future__ import annotations

import json
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from conftest import ROOT
from nudyn_validation.compare import EXTRA_OUTPUTS, Settings, run_scenarios
from nudyn_validation.corpus import (
    BUS_MASS,
    BUS_NAME,
    entry_points,
    evaluation_error,
    mount_on_bus,
    refusal_cause,
)
from nudyn_validation.corpus import STRIPPED
from nudyn_driver.cli import Nudyn
from nudyn_validation.judgement import AGREES, CHAOTIC, DISAGREES, TWIN_NUDGE, TWINS, judge, passes, twin_nudges
from nudyn_validation.mujoco_reference import load_model

CORPUS = ROOT / "tests" / "fixtures" / "corpus"
PENDULUM = CORPUS / "pendulum" / "pendulum.xml"


@pytest.mark.parametrize(
    "error, twin, verdict",
    [
        (1e-12, 1e-14, AGREES),  # within the tolerance, however quiet the twin
        (1e-6, 0.0, AGREES),  # on the tolerance
        (5e-6, 1e-6, CHAOTIC),  # over it, within 10 × the twin
        (9e-6, 1e-6, CHAOTIC),  # just within 10 × the twin
        (2e-5, 1e-6, DISAGREES),  # beyond 10 × the twin
        (2e-6, 1e-12, DISAGREES),  # over the tolerance with a quiet twin
        (1e-1, 1e-3, DISAGREES),  # the twin beyond the tolerance, nudyn 100 × farther
    ],
)
def test_judgement(error, twin, verdict):
    assert judge(error, twin, 1e-6) == verdict
    assert passes(verdict) == (verdict != DISAGREES)


def test_twins_start_apart_in_different_directions():
    nudges = twin_nudges(5, seed=1)
    assert len(nudges) == TWINS == 3
    assert all(np.all(np.abs(n) == TWIN_NUDGE) for n in nudges)
    assert np.all(nudges[0] > 0) and np.all(nudges[1] < 0) and len(set(np.sign(nudges[2]))) == 2
    np.testing.assert_array_equal(twin_nudges(5, seed=1)[2], nudges[2])  # a run repeats its draw


def test_the_twin_divergence_is_the_largest_twins(nudyn, tmp_path):
    """Each twin is a MuJoCo run of its own; the divergence judged is the
    largest of theirs at each time."""
    fmu = tmp_path / "pendulum.fmu"
    Nudyn(nudyn).export(PENDULUM, fmu, outputs=EXTRA_OUTPUTS)
    settings = Settings(duration=0.3)
    result = run_scenarios(PENDULUM, fmu, ["actuated"], settings).results[0]
    assert len(result.twins) == TWINS
    each = [np.max(np.abs(t.nu - result.mujoco.nu), axis=1) for t in result.twins]
    assert len({float(np.max(e)) for e in each}) == TWINS  # the twins did run apart
    assert np.all(result.twin_divergence() >= np.maximum.reduce(each))


def test_refusals_group_by_feature():
    """Files, lines, names, quoted paths and numbers are left out of a
    refusal's cause, so that two files refused for one feature count together."""
    faces = [
        "line 35: <mesh name=\"camera\">: mesh file '/a/camera.obj': line 25418: a face of 11 vertices (reads quads)",
        "cannot import b.xml: line 21: <mesh name=\"mount\">: mesh file '/b/m.obj': line 7: a face of 24 vertices (reads quads)",
    ]
    assert {refusal_cause(m) for m in faces} == {"<mesh>: mesh file '…': a face of N vertices (reads quads)"}
    assert refusal_cause("line 3: <option>: not supported: a nonzero medium 1.2e-3 adds fluid forces") == (
        "<option>: not supported: a nonzero medium N adds fluid forces"
    )


def test_entry_points_are_the_models_not_their_parts_or_scenes():
    """servo_arm.xml is included by servo.xml; scene.xml only surrounds
    pendulum.xml, which stays the model."""
    found = [p.relative_to(CORPUS.resolve()).as_posix() for p in entry_points(CORPUS)]
    assert found == ["absent_mesh.xml", "absent_visual_mesh.xml", "pendulum/pendulum.xml", "servo/servo.xml",
                     "stiff.xml", "windy.xml"]


def test_bus_form_mounts_the_model_on_a_free_bus(tmp_path):
    """The wrapper keeps every body where it was, adds the bus's 7
    coordinates and 500 kg, merges the includes and drops the robot's own
    free joint (it rides the bus)."""
    for model, extra_nq in ((PENDULUM, 7), (CORPUS / "servo" / "servo.xml", 7), (CORPUS / "windy.xml", 0)):
        published = mujoco.MjModel.from_xml_path(str(model))
        bus = mujoco.MjModel.from_xml_path(str(mount_on_bus(model, tmp_path / model.parent.name / model.name)))
        assert bus.nq == published.nq + extra_nq, model
        assert bus.nu == published.nu and bus.body(BUS_NAME).mass[0] == BUS_MASS
        assert bus.jnt_bodyid[0] == bus.body(BUS_NAME).id and bus.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
        d_pub, d_bus = mujoco.MjData(published), mujoco.MjData(bus)
        mujoco.mj_kinematics(published, d_pub)
        mujoco.mj_kinematics(bus, d_bus)
        for b in range(1, published.nbody):
            name = published.body(b).name
            np.testing.assert_allclose(d_bus.body(name).xpos, d_pub.body(name).xpos, atol=1e-15)
            assert bus.body(name).mass[0] == pytest.approx(published.body(b).mass[0], rel=1e-15)


def run_corpus_command(nudyn, out, *extra):
    return subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "validate.py"), "--corpus", str(CORPUS), "--duration", "0.2",
         "--states", "4", "--out", str(out), "--nudyn", str(nudyn), *extra],
        capture_output=True, text=True, cwd=ROOT,
    )


def test_corpus_command_writes_the_table(nudyn, tmp_path):
    out = tmp_path / "corpus"
    proc = run_corpus_command(nudyn, out)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    numbers = json.loads((out / "corpus.json").read_text())
    rows = {(r["model"], r["form"]): r for r in numbers["rows"]}
    assert len(rows) == 12
    for form in ("published", "bus"):
        for model in ("pendulum/pendulum.xml", "servo/servo.xml"):
            row = rows[model, form]
            assert row["status"] == "exported" and row["verdict"] == AGREES, row
            assert row["scenario"] == "actuated" and row["evaluation_error"] < 1e-12, row
            # The twin did start elsewhere, and nudyn is nearer MuJoCo than the tolerance.
            assert 0.0 < row["twin_divergence"] < 1e-9 and row["trajectory_error"] < 1e-9, row
        windy = rows["windy.xml", form]
        assert windy["status"] == windy["verdict"] == "refused" and "wind" in windy["message"], windy
        assert windy["message"].startswith("line "), windy
        # Too stiff for the step: MuJoCo's own run blows up too, which the row says.
        stiff = rows["stiff.xml", form]
        assert stiff["verdict"] == "unstable at this step" and stiff["evaluation_error"] < 1e-12, stiff
        assert "MuJoCo alone: mjWARN_BAD" in stiff["message"], stiff
        absent = rows["absent_mesh.xml", form]
        assert absent["verdict"] == "files absent" and "no_such_hull.stl" in absent["message"], absent
        assert rows["absent_visual_mesh.xml", form]["verdict"] == "files absent"
        assert numbers["summary"]["verdicts"][form] == {
            AGREES: 2, "files absent": 2, "refused": 1, "unstable at this step": 1
        }
        assert list(numbers["summary"]["refusals"][form]) == [
            "<option>: not supported: wind acts through fluid forces, which nudyn does not model"
        ]
    table = (out / "corpus.md").read_text()
    assert table.count(f"| {AGREES} |") == 4 + 1  # four rows, and the summary's line
    assert "| windy.xml | bus | 6 | refused: line 2: &lt;option>: not supported: wind" in table
    # --resume keeps every row that neither failed nor timed out: nothing runs again.
    resumed = run_corpus_command(nudyn, out, "--resume")
    assert resumed.returncode == 0 and "12 jobs (12 kept from the last run)" in resumed.stdout, resumed.stdout
    assert json.loads((out / "corpus.json").read_text())["rows"] == numbers["rows"]
    other = run_corpus_command(nudyn, out, "--resume", "--seed", "2")
    assert other.returncode == 2 and "was run with other settings" in other.stderr, other.stderr


def test_absent_meshes_are_stripped_on_request(nudyn, tmp_path):
    """With --strip-absent-meshes a model runs without the meshes whose
    files are absent, and its verdict says so: the pendulum whose links
    carry their own inertia agrees; the free hull whose only mass was its
    mesh is left massless, which MuJoCo refuses to load."""
    out = tmp_path / "corpus"
    proc = run_corpus_command(nudyn, out, "--strip-absent-meshes", "--exclude", "[!a]*", "--exclude", "*/*")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    numbers = json.loads((out / "corpus.json").read_text())
    assert numbers["settings"]["strip_absent_meshes"] is True
    rows = {(r["model"], r["form"]): r for r in numbers["rows"]}
    assert {model for model, _ in rows} == {"absent_mesh.xml", "absent_visual_mesh.xml"}
    for form in ("published", "bus"):
        pendulum = rows["absent_visual_mesh.xml", form]
        assert pendulum["verdict"] == f"{AGREES}, {STRIPPED}", pendulum
        assert pendulum["stripped_meshes"] == ["link_visual", "no_such_tip"], pendulum
        assert pendulum["evaluation_error"] < 1e-12 and pendulum["nv"] == (2 if form == "published" else 8)
    hull = rows["absent_mesh.xml", "published"]
    assert hull["verdict"] == f"MuJoCo cannot load, {STRIPPED}" and "mass" in hull["message"], hull
    # On the bus the hull lost its free joint: a massless part of the bus is no fault.
    assert rows["absent_mesh.xml", "bus"]["verdict"] == f"{AGREES}, {STRIPPED}"
    # The stripped file keeps everything else: the dynamics as published.
    stripped = load_model(out / "models" / "absent_visual_mesh" / "published" / "absent_visual_mesh.stripped.xml")
    assert stripped.ngeom == 1 and stripped.npair == 0 and stripped.nmesh == 0
    np.testing.assert_array_equal(stripped.body_mass[1:], [1.5, 0.8])


def test_a_wrong_model_is_caught(cli, tmp_path):
    """Evaluations and trajectory of an FMU exported from a slightly
    different pendulum (a heavier lower link) disagree: the checks can fail."""
    heavier = tmp_path / "heavier.xml"
    heavier.write_text(PENDULUM.read_text().replace('size="0.03"', 'size="0.031"'))
    model = load_model(PENDULUM)
    assert evaluation_error(cli, heavier, model, 4, 1) > 1e-3
    fmu = cli.export(heavier, tmp_path / "heavier.fmu", outputs=EXTRA_OUTPUTS)
    summary = run_scenarios(PENDULUM, fmu, ["actuated"], Settings(duration=0.2)).results[0].summary()
    assert summary["verdict"] == DISAGREES and not summary["passed"], summary
