"""`scripts/validate.py MODEL.xml`: export the FMU, run it in FMPy against
MuJoCo on the same MJCF, and write the evidence (PNG, table.md, results.json);
`--corpus DIR`: the same judgement on every model under DIR (corpus.py)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from nudyn_driver.errors import DriverError
from nudyn_driver.locations import nudyn_binary, output_dir

from .compare import Settings, ValidationError, validate_model
from .corpus import FORMS, CorpusError, run_corpus, write_report
from .judgement import DISAGREES
from .report import write
from .scenarios import SCENARIO_NAMES



def parse_parameter(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    try:
        if not sep:
            raise ValueError
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=NUMBER, got '{text}'") from None


def arguments(argv):
    defaults = Settings()
    p = argparse.ArgumentParser(
        description="Export MODEL.xml as an FMU with nudyn, run it in FMPy and MuJoCo from the same "
        "state with the same held inputs, and compare theta, nu, kinetic energy and momentum.",
    )
    p.add_argument("model", type=Path, nargs="?", help="MJCF file (or --corpus DIR)")
    corpus = p.add_argument_group("corpus", "every model under a directory (docs/validation.md#a-corpus-of-models)")
    corpus.add_argument("--corpus", type=Path, metavar="DIR",
                        help="export every model entry point under DIR, as published and on a free bus, and check "
                        "evaluations and a trajectory against MuJoCo; writes corpus.md and corpus.json")
    corpus.add_argument("--jobs", type=int, default=1, help="models run at a time (default %(default)s)")
    corpus.add_argument("--timeout", type=float, default=600.0,
                        help="seconds one model in one form may take (default %(default)s)")
    corpus.add_argument("--states", type=int, default=10,
                        help="random states of the single evaluations (default %(default)s)")
    corpus.add_argument("--forms", default=",".join(FORMS),
                        help="comma-separated forms to run (default %(default)s)")
    corpus.add_argument("--exclude", action="append", default=[], metavar="GLOB",
                        help="leave out models whose path below DIR matches (repeatable)")
    corpus.add_argument("--resume", action="store_true",
                        help="keep the rows of the last corpus.json in --out (same settings) that neither "
                        "failed nor timed out, and run the others")
    corpus.add_argument("--strip-absent-meshes", action="store_true",
                        help="run a model whose mesh files are absent without those meshes and their geoms "
                        "(verdict marked; a body whose mass came from them is lighter than as published)")
    p.add_argument(
        "--scenario",
        action="append",
        choices=SCENARIO_NAMES,
        help="run only this scenario (repeatable; default: all that apply, 'gravity' only with gravity, 'actuated' only with actuators)",
    )
    p.add_argument("--duration", type=float, default=defaults.duration, help="seconds (default %(default)s)")
    p.add_argument(
        "--comm-step", type=float, default=defaults.communication_step, help="communication step, s (default %(default)s)"
    )
    p.add_argument("--mujoco-step", type=float, default=defaults.mujoco_step, help="MuJoCo's RK4 step, s (default %(default)s)")
    p.add_argument("--method", default=defaults.method, help="the FMU's integration method, by item name (default %(default)s)")
    p.add_argument(
        "--fmu-parameter",
        action="append",
        type=parse_parameter,
        default=[],
        metavar="NAME=VALUE",
        help="set a Real parameter of the FMU by name (repeatable; with rk4, max_step defaults to "
        f"{defaults.parameters()['max_step']:g} s)",
    )
    p.add_argument("--fmi-version", type=int, choices=(2, 3), default=defaults.fmi_version,
                   help="the FMU's FMI version (default %(default)s)")
    p.add_argument("--interface", choices=("cs", "me"), default=defaults.interface,
                   help="co-simulation (the FMU's own integrator) or model exchange under FMPy's CVODE "
                   "(default %(default)s)")
    p.add_argument("--rtol", type=float, default=defaults.relative_tolerance,
                   help="CVODE's relative tolerance with --interface me (default %(default)s)")
    p.add_argument("--seed", type=int, default=defaults.seed, help="seed of the initial state and the sine (default %(default)s)")
    p.add_argument(
        "--wrench-inputs",
        default="",
        metavar="BODY[,BODY...]",
        help="export the FMU with wrench inputs on these bodies and run the 'wrenched' scenario on them",
    )
    p.add_argument("--out", type=Path, help="output directory (default out/validation/MODEL)")
    p.add_argument(
        "--nudyn",
        type=Path,
        default=nudyn_binary(),
        help="the nudyn binary (default $NUDYN_BIN or target/release/nudyn)",
    )
    return p.parse_args(argv)


def corpus_main(args, settings: Settings) -> int:
    forms = tuple(f for f in args.forms.split(",") if f)
    unknown = sorted(set(forms) - set(FORMS))
    if unknown or not forms:
        print(f"validate: unknown form {', '.join(unknown) or '(none)'} (known: {', '.join(FORMS)})", file=sys.stderr)
        return 2
    out = args.out or output_dir("corpus", args.corpus.resolve().name)
    try:
        settings.check()
        rows = run_corpus(args.corpus, out, args.nudyn, settings, jobs=args.jobs, timeout=args.timeout,
                          states=args.states, forms=forms, exclude=args.exclude, resume=args.resume,
                          strip_absent_meshes=args.strip_absent_meshes)
    except (CorpusError, ValidationError) as e:
        print(f"validate: {e}", file=sys.stderr)
        return 2
    paths = write_report(rows, settings, args.states, args.corpus, out, args.strip_absent_meshes)
    print(f"table:   {paths['table']}")
    print(f"numbers: {paths['json']}")
    if any(r.verdict.startswith(DISAGREES) for r in rows):
        print("validate: some model disagrees with MuJoCo (see the table)", file=sys.stderr)
        return 1
    return 0


def main(argv=None) -> int:
    args = arguments(argv)
    if (args.model is None) == (args.corpus is None):
        print("validate: give either MODEL.xml or --corpus DIR", file=sys.stderr)
        return 2
    settings = Settings(
        duration=args.duration,
        communication_step=args.comm_step,
        mujoco_step=args.mujoco_step,
        method=args.method,
        fmu_parameters=dict(args.fmu_parameter),
        seed=args.seed,
        fmi_version=args.fmi_version,
        interface=args.interface,
        relative_tolerance=args.rtol,
        wrench_bodies=tuple(b for b in args.wrench_inputs.split(",") if b),
    )
    if args.corpus is not None:
        return corpus_main(args, settings)
    out = args.out or output_dir("validation", args.model.stem)
    if not args.model.is_file():
        print(f"validate: no such file: {args.model}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    try:
        validation = validate_model(args.model, out / f"{args.model.stem}.fmu", args.nudyn, args.scenario, settings)
    except (ValidationError, DriverError) as e:
        print(f"validate: {e}", file=sys.stderr)
        return 2
    paths = write(validation, out)
    print(paths["table"].read_text())
    print(f"FMU:     {validation.fmu_path}")
    if validation.rigid_fmu_path is not None:
        print(f"rigid:   {validation.rigid_fmu_path} (the modes frozen; compared with MuJoCo)")
    for label, key in (("picture", "plot"), ("table", "table"), ("numbers", "json")):
        print(f"{label + ':':8s} {paths[key]}")
    if not validation.passed:
        print("validate: some scenario exceeds its tolerance (see the table)", file=sys.stderr)
        return 1
    return 0
