"""The modelDescription.xml written by the Rust crate `modeldescription`
(its `write_example` example) validates against the official FMI 2.0 XML
schema shipped inside FMPy, passes FMPy's own semantic validation, and
reads back in FMPy with the values the Rust side wrote."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import fmpy
import pytest
from fmpy.model_description import read_model_description
from fmpy.validation import validate_fmu
from lxml import etree

ROOT = Path(__file__).resolve().parents[2]
FMI2_SCHEMA = Path(fmpy.__file__).parent / "schema" / "fmi2" / "fmi2ModelDescription.xsd"
# --release: scripts/test.sh has built the example there already, with the
# same features (workspace-hack), so this compiles nothing; a debug build
# would compile the crate and its dependencies again.
EXAMPLE_COMMAND = ["cargo", "run", "-q", "--release", "-p", "modeldescription", "--example", "write_example"]


@pytest.fixture(scope="module")
def example_xml() -> str:
    """The document printed by the Rust example; fails (never skips) when
    cargo is missing or the example fails."""
    if shutil.which("cargo") is None:
        pytest.fail("cargo not found on PATH", pytrace=False)
    proc = subprocess.run(
        EXAMPLE_COMMAND, cwd=ROOT, capture_output=True, text=True, timeout=900
    )
    if proc.returncode != 0:
        pytest.fail(
            f"{' '.join(EXAMPLE_COMMAND)} exited {proc.returncode}\nstderr:\n{proc.stderr}",
            pytrace=False,
        )
    return proc.stdout


@pytest.fixture
def extracted_fmu(tmp_path: Path, example_xml: str) -> Path:
    """A directory laid out like an extracted FMU: modelDescription.xml only."""
    (tmp_path / "modelDescription.xml").write_text(example_xml, encoding="utf-8")
    return tmp_path


@pytest.fixture(scope="module")
def schema() -> etree.XMLSchema:
    assert FMI2_SCHEMA.is_file(), f"FMPy ships no FMI 2.0 schema at {FMI2_SCHEMA}"
    return etree.XMLSchema(etree.parse(str(FMI2_SCHEMA)))


def schema_errors(schema: etree.XMLSchema, xml: str) -> list[str]:
    document = etree.fromstring(xml.encode("utf-8"))
    if schema.validate(document):
        return []
    return [f"line {e.line}: {e.message}" for e in schema.error_log]


def test_example_validates_against_the_fmi2_schema(schema, example_xml):
    assert example_xml.startswith('<?xml version="1.0" encoding="UTF-8"?>\n')
    assert schema_errors(schema, example_xml) == []


def test_schema_check_catches_a_misspelling(schema, example_xml):
    # Guards against a check that passes everything.
    broken = example_xml.replace('causality="output"', 'causality="Output"', 1)
    assert broken != example_xml
    errors = schema_errors(schema, broken)
    assert errors and "causality" in errors[0], errors


def test_fmpy_validation_finds_no_problems(extracted_fmu):
    # XSD, unique names, structured-name grammar, start values,
    # causality/variability/initial combinations, units, model structure.
    assert validate_fmu(str(extracted_fmu)) == []


def test_fmpy_reads_the_values_rust_wrote(extracted_fmu):
    md = read_model_description(str(extracted_fmu), validate=True)

    assert md.fmiVersion == "2.0"
    assert md.modelName == "arm"
    assert md.guid == "{8c4e810f-3df3-4a00-8276-176fa3c9f000}"
    assert md.variableNamingConvention == "structured"
    assert md.modelExchange is None
    cs = md.coSimulation
    assert cs.modelIdentifier == "arm"
    assert cs.canHandleVariableCommunicationStepSize is True
    assert cs.canNotUseMemoryManagementFunctions is True
    assert cs.canGetAndSetFMUstate is False

    assert float(md.defaultExperiment.startTime) == 0.0
    assert float(md.defaultExperiment.stopTime) == 10.0
    assert float(md.defaultExperiment.tolerance) == 1e-6
    assert float(md.defaultExperiment.stepSize) == 1e-3

    units = {u.name: u for u in md.unitDefinitions}
    torque = units["N.m"].baseUnit
    assert (torque.kg, torque.m, torque.s, torque.rad) == (1, 2, -2, 0)
    assert units["degC"].baseUnit.offset == 273.15
    assert [d.name for d in units["rad/s"].displayUnits] == ["deg/s"]

    types = {t.name: t for t in md.typeDefinitions}
    method = types["IntegratorMethod"]
    assert method.type == "Enumeration"
    assert [(i.name, i.value) for i in method.items] == [("euler", "1"), ("rk4", "2")]

    variables = {v.name: v for v in md.modelVariables}
    assert [(v.name, v.causality, v.variability) for v in md.modelVariables[:5]] == [
        ("time", "independent", "continuous"),
        ("tau", "input", "continuous"),
        ("m", "parameter", "fixed"),
        ("q", "output", "continuous"),
        ("dq", "output", "continuous"),
    ]
    assert variables["q"].initial == "exact"
    assert float(variables["q"].start) == 0.1
    assert variables["m"].declaredType.name == "Mass"
    assert variables["integrator"].type == "Enumeration"
    assert variables["integrator"].declaredType is method
    assert variables["der(q)"].derivative is variables["q"]
    assert variables["label"].start == 'arm <1> & "2"'

    assert [u.variable.name for u in md.outputs] == ["q", "dq", "saturated"]
    assert [u.variable.name for u in md.derivatives] == ["der(dq)", "der(q)"]
    assert [d.name for d in md.derivatives[0].dependencies] == ["tau", "q", "dq"]
    assert md.derivatives[0].dependenciesKind == ["constant", "dependent", "dependent"]
    assert md.outputs[2].dependencies == []
    assert [u.variable.name for u in md.initialUnknowns] == [
        "der(dq)",
        "der(q)",
        "saturated",
        "inertia",
    ]
