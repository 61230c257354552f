"""documentation/index.html inside every FMU: the vehicle's joints as
`nudyn describe` lists them, and every variable of the modelDescription
with its value reference, causality and description, for the plant and the
controller, FMI 2.0 and 3.0; escaped (a name with markup characters reads
back as written)."""

from __future__ import annotations

import html
import json
import subprocess
import zipfile
from html.parser import HTMLParser

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from conftest import ROOT


class Tables(HTMLParser):
    """Every table row's cell texts, and the title."""

    def __init__(self):
        super().__init__()
        self.rows, self.cell, self.title, self._in = [], None, "", None

    def handle_starttag(self, tag, attrs):
        if tag == "tr":
            self.rows.append([])
        elif tag in ("td", "th"):
            self.cell = ""
        self._in = tag

    def handle_endtag(self, tag):
        if tag in ("td", "th"):
            self.rows[-1].append(self.cell)
            self.cell = None
        self._in = None

    def handle_data(self, data):
        if self.cell is not None:
            self.cell += data
        elif self._in == "title":
            self.title += data


def page(fmu) -> Tables:
    with zipfile.ZipFile(fmu) as archive:
        tables = Tables()
        tables.feed(archive.read("documentation/index.html").decode())
    return tables


@pytest.mark.parametrize("controller", [False, True], ids=["plant", "controller"])
@pytest.mark.parametrize("fmi_version", [2, 3])
def test_the_fmu_documents_its_joints_and_variables(cli, nudyn, tmp_path, controller, fmi_version):
    model = ROOT / "examples" / ("bus_arm7.xml" if controller else "servicer.xml")
    fmu = cli.export(model, tmp_path / "x.fmu", controller=controller, fmi_version=fmi_version)
    tables = page(fmu)
    described = json.loads(subprocess.run([str(nudyn), "describe", str(model), "--json"], capture_output=True,
                                          text=True, check=True).stdout)
    joints = [row for row in tables.rows if len(row) == 5 and row[0] != "joint"]
    assert [(row[0], row[2]) for row in joints] == [(j["name"], j["kind"]) for j in described["joints"]]
    variables = {row[0]: row for row in tables.rows if len(row) == 6 and row[0] != "name"}
    description = read_model_description(str(fmu))
    assert set(variables) == {v.name for v in description.modelVariables}
    for v in description.modelVariables:
        row = variables[v.name]
        assert int(row[1]) == v.valueReference and row[2] == v.causality, row
        assert row[5] == (v.description or ""), row
    assert validate_fmu(str(fmu)) == []


def paragraphs(fmu) -> str:
    """The page as text: its markup with the entities read."""
    with zipfile.ZipFile(fmu) as archive:
        return html.unescape(archive.read("documentation/index.html").decode())


def test_the_page_names_gravity_compensation_and_tendons(cli, tmp_path):
    """A vehicle with them says so; one without says nothing of them."""
    gravcomp = paragraphs(cli.export(ROOT / "tests" / "fixtures" / "gravcomp" / "arm_on_bus.xml", tmp_path / "g.fmu"))
    assert "Gravity compensation: MuJoCo's <code>qfrc_gravcomp</code>" in gravcomp
    assert "actuator force (<code>actuatorgravcomp</code>)" in gravcomp
    tendons = paragraphs(cli.export(ROOT / "tests" / "fixtures" / "tendons" / "tendon_wrap.xml", tmp_path / "t.fmu"))
    assert "Tendons: <spatial> tendon 'flexor', <spatial> tendon 'strap', <spatial> tendon 'cord' (" in tendons
    plain = paragraphs(cli.export(ROOT / "examples" / "fixed_rig.xml", tmp_path / "r.fmu"))
    assert "Gravity compensation" not in plain and "Tendons:" not in plain


def test_markup_in_names_is_escaped(cli, tmp_path):
    xml = (ROOT / "examples" / "fixed_rig.xml").read_text().replace('model="fixed_rig"', 'model="rig &lt;A&amp;B&gt;"')
    source = tmp_path / "rig.xml"
    source.write_text(xml)
    tables = page(cli.export(source, tmp_path / "rig.fmu"))
    assert tables.title == "rig <A&B>"
