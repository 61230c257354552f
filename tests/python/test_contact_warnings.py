"""nudyn models no contacts; it warns of each pair of geoms MuJoCo would
collide at the initial pose (src/mjcf/contacts.rs says what it checks).
On small fixtures (tests/fixtures/mjcf/contacts/: overlapping free
spheres, the filters MuJoCo applies, a contact exclusion and
filterparent disabled), the pairs named must be exactly those of MuJoCo
4.0's contacts after mj_forward."""

from __future__ import annotations

import re
import subprocess

import mujoco
import pytest

from conftest import ROOT

CONTACT_FIXTURES = ROOT / "tests" / "fixtures" / "mjcf" / "contacts"
FIXTURES = sorted(CONTACT_FIXTURES.glob("*.xml"))
TOUCHES = re.compile(r'<geom name="([^"]+)">: touches <geom name="([^"]+)">')


def mujoco_pairs(path):
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return {frozenset((m.geom(c.geom1).name, m.geom(c.geom2).name)) for c in d.contact[: d.ncon]}


def test_there_are_fixtures():
    assert len(FIXTURES) == 3


@pytest.mark.parametrize("path", FIXTURES, ids=lambda p: p.stem)
def test_the_contact_warnings_name_mujocos_pairs(nudyn, path):
    proc = subprocess.run([str(nudyn), "describe", str(path)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    warned = [frozenset(pair) for pair in TOUCHES.findall(proc.stderr)]
    assert len(warned) == len(set(warned)), proc.stderr
    expected = mujoco_pairs(path)
    assert expected, "each fixture has contacts"
    assert set(warned) == expected, proc.stderr


def test_no_warning_once_contacts_are_disabled(nudyn, tmp_path):
    path = tmp_path / "off.xml"
    text = (CONTACT_FIXTURES / "free_spheres.xml").read_text()
    path.write_text(text.replace("<worldbody>", '<option><flag contact="disable"/></option><worldbody>'))
    assert mujoco_pairs(path) == set()
    proc = subprocess.run([str(nudyn), "describe", str(path)], capture_output=True, text=True)
    assert proc.returncode == 0 and "touches" not in proc.stderr, proc.stderr
