"""`nudyn export` never leaves a broken FMU behind: it writes a temporary
file beside the output and renames it into place, so concurrent exports
and failures leave either a whole archive or what was there before, and it
refuses to overwrite the MJCF file it reads."""

from __future__ import annotations

import os
import stat
import subprocess
import zipfile
from concurrent.futures import ThreadPoolExecutor

from conftest import EXAMPLES_DIR

MODEL = EXAMPLES_DIR / "fixed_rig.xml"


def export(nudyn, fmu_library, model, output, *options):
    # linux64 only (test_fmu_platforms.py covers the others).
    env = {**os.environ, "NUDYN_FMU_LIB": str(fmu_library), "NUDYN_FMU_BINARIES": "/nonexistent"}
    return subprocess.run([str(nudyn), "export", str(model), "-o", str(output), *options],
                          capture_output=True, text=True, env=env)


def test_the_input_is_never_overwritten(nudyn, fmu_library, tmp_path):
    model = tmp_path / "rig.xml"
    model.write_bytes(MODEL.read_bytes())
    for output in (model, tmp_path / "." / "rig.xml"):
        proc = export(nudyn, fmu_library, model, output)
        assert proc.returncode == 1 and "is the input MJCF file" in proc.stderr, proc.stderr
    assert model.read_bytes() == MODEL.read_bytes()


def test_concurrent_exports_to_one_path_leave_one_whole_archive(nudyn, fmu_library, tmp_path):
    fmu = tmp_path / "rig.fmu"
    option_sets = [(), ("--outputs", "qvel,kinetic_energy,power,momentum,energy_residual")] * 2
    with ThreadPoolExecutor(max_workers=4) as pool:
        runs = list(pool.map(lambda options: export(nudyn, fmu_library, MODEL, fmu, *options), option_sets))
    assert all(run.returncode == 0 for run in runs), [run.stderr for run in runs]
    with zipfile.ZipFile(fmu) as archive:
        assert archive.testzip() is None
        assert sorted(archive.namelist()) == [
            "binaries/linux64/fixed_rig.so", "documentation/index.html", "modelDescription.xml", "resources/model.json"
        ]
    assert os.stat(fmu).st_mode & 0o777 == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["rig.fmu"], "no temporary file is left behind"


def test_a_failed_export_keeps_what_was_there(nudyn, fmu_library, tmp_path):
    fmu = tmp_path / "rig.fmu"
    assert export(nudyn, fmu_library, MODEL, fmu).returncode == 0
    good = fmu.read_bytes()
    # The binary cannot be read: refused before anything is written.
    env = {**os.environ, "NUDYN_FMU_LIB": str(tmp_path / "missing.so")}
    proc = subprocess.run([str(nudyn), "export", str(MODEL), "-o", str(fmu), "--outputs", "qvel"],
                          capture_output=True, text=True, env=env)
    assert proc.returncode == 1 and "missing.so" in proc.stderr
    assert fmu.read_bytes() == good
    # The archive is written but cannot take the output's place (a directory is there).
    occupied = tmp_path / "occupied.fmu"
    occupied.mkdir()
    (occupied / "keep").write_text("kept")
    proc = export(nudyn, fmu_library, MODEL, occupied)
    assert proc.returncode == 1 and "occupied.fmu" in proc.stderr, proc.stderr
    assert (occupied / "keep").read_text() == "kept"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["occupied.fmu", "rig.fmu"], "no temporary file is left"


def test_only_a_regular_file_or_a_new_path_is_replaced(nudyn, fmu_library, tmp_path):
    """The temporary file is never renamed over anything else: a FIFO stays
    a FIFO (so would a device node: as root, `-o /dev/null` once became a
    regular file), and a symbolic link to an FMU is written through."""
    fifo = tmp_path / "pipe.fmu"
    os.mkfifo(fifo)
    proc = export(nudyn, fmu_library, MODEL, fifo)
    assert proc.returncode == 1, proc.stderr
    assert f"{fifo} is a FIFO, not a regular file: nudyn writes only regular files and new paths" in proc.stderr
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    to_fifo = tmp_path / "to_pipe.fmu"
    to_fifo.symlink_to(fifo)
    proc = export(nudyn, fmu_library, MODEL, to_fifo)
    assert proc.returncode == 1 and f"{to_fifo} is a FIFO" in proc.stderr, proc.stderr
    fmu, link = tmp_path / "rig.fmu", tmp_path / "link.fmu"
    fmu.write_bytes(b"old")
    link.symlink_to(fmu)
    assert export(nudyn, fmu_library, MODEL, link).returncode == 0
    assert link.is_symlink() and zipfile.is_zipfile(fmu)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.fmu", "pipe.fmu", "rig.fmu", "to_pipe.fmu"]


def shared_library(tmp_path, name, functions):
    """A shared library built with gcc, exporting `functions`."""
    source = tmp_path / f"{name}.c"
    source.write_text("".join(f"int {f}(void) {{ return 0; }}\n" for f in functions) or "int nothing;\n")
    library = tmp_path / f"{name}.so"
    subprocess.run(["gcc", "-shared", "-fPIC", "-o", str(library), str(source)], check=True)
    return library


def test_a_binary_that_cannot_be_the_fmus_is_refused(nudyn, fmu_library, tmp_path):
    """NUDYN_FMU_LIB must name an x86_64 Linux shared library exporting the
    functions of the FMI version: anything else is refused before an FMU is
    written, with what the file is instead."""
    text = tmp_path / "passwd"
    text.write_text("root:x:0:0:root:/root:/bin/bash\n")
    relocatable = tmp_path / "object.o"
    subprocess.run(["gcc", "-c", "-x", "c", "-o", str(relocatable), "-"], input="int f(void) { return 0; }\n",
                   text=True, check=True)
    partial = ["fmi2Instantiate", "fmi2DoStep"]
    cases = {
        text: "it is not a shared library",
        relocatable: "it is an ELF file of kind Relocatable, not a shared library",
        shared_library(tmp_path, "unrelated", []): "it is a shared library that exports none of the 44 FMI 2.0 functions",
        shared_library(tmp_path, "partial", partial): "it is a shared library that does not export 42 of the FMI 2.0 functions "
                                                      "(fmi2GetTypesPlatform, fmi2GetVersion,",
    }
    fmu = tmp_path / "rig.fmu"
    for library, says in cases.items():
        env = {**os.environ, "NUDYN_FMU_LIB": str(library)}
        proc = subprocess.run([str(nudyn), "export", str(MODEL), "-o", str(fmu)], capture_output=True, text=True,
                              env=env)
        assert proc.returncode == 1, proc.stderr
        assert f"{library} cannot be the FMU's binary: {says}" in proc.stderr, proc.stderr
        assert not fmu.exists()
    # An FMI 2.0-only library cannot be an FMI 3.0 FMU's binary.
    symbols = subprocess.run(["nm", "-D", "--defined-only", str(fmu_library)], capture_output=True, text=True,
                             check=True).stdout.split()
    fmi2_only = shared_library(tmp_path, "fmi2_only", [name for name in symbols if name.startswith("fmi2")])
    env = {**os.environ, "NUDYN_FMU_LIB": str(fmi2_only)}
    proc = subprocess.run([str(nudyn), "export", str(MODEL), "-o", str(fmu), "--fmi-version", "3"],
                          capture_output=True, text=True, env=env)
    assert proc.returncode == 1 and "exports none of the 75 FMI 3.0 functions" in proc.stderr, proc.stderr
    assert export(nudyn, fmu_library, MODEL, fmu).returncode == 0


def test_an_os_error_is_said_once(nudyn, fmu_library, tmp_path):
    proc = export(nudyn, fmu_library, MODEL, tmp_path / "missing" / "rig.fmu")
    assert proc.returncode == 1
    assert proc.stderr.strip() == (f"nudyn: error: cannot export {tmp_path}/missing/rig.fmu: {tmp_path}/missing: "
                                   "No such file or directory (os error 2)")


def test_a_model_identifier_too_long_to_extract_or_reserved_on_windows_is_refused(nudyn, fmu_library, tmp_path):
    from fmpy import extract

    # The longest allowed identifier gives an FMU FMPy extracts.
    longest = "x" * 200
    fmu = tmp_path / "long.fmu"
    proc = export(nudyn, fmu_library, MODEL, fmu, "--model-identifier", longest)
    assert proc.returncode == 0, proc.stderr
    unpacked = extract(str(fmu), unzipdir=str(tmp_path / "long"))
    assert (tmp_path / "long" / "binaries" / "linux64" / f"{longest}.so").is_file(), unpacked
    for identifier, reason in [("x" * 300, "longer than 200"), ("con", "Windows reserves"),
                               ("LPT1", "Windows reserves"), ("Nul", "Windows reserves")]:
        output = tmp_path / "refused.fmu"
        proc = export(nudyn, fmu_library, MODEL, output, "--model-identifier", identifier)
        assert proc.returncode == 1 and reason in proc.stderr, (identifier, proc.stderr)
        assert not output.exists(), identifier
