"""What a campaign's rows were flown from, kept as OUT/campaign.json beside
them: everything in the campaign file that decides a row (the seed, the
flight, the fixed parameters, the dispersions, the schedules, the metrics;
not the name or the number of cases) and a hash of each FMU's contents. A
rerun into the same OUT resumes only when this matches; otherwise it is
refused with what differs, or, with `overwrite`, the old rows are removed
and the campaign starts afresh."""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
import zipfile
from pathlib import Path

from .files import write_atomically
from .spec import Campaign, CampaignError

RECORD = "campaign.json"
# The one line of an FMU that changes from export to export of the same model.
_GENERATED_AT = re.compile(rb' generationDateAndTime="[^"]*"')


def fmu_hash(fmu: bytes) -> str:
    """SHA-256 of the FMU's files (names and contents; the model
    description without its generation time), so that the same model
    exported by the same nudyn hashes the same."""
    digest = hashlib.sha256()
    with zipfile.ZipFile(io.BytesIO(fmu)) as archive:
        for name in sorted(archive.namelist()):
            content = archive.read(name)
            if name.endswith("modelDescription.xml"):
                content = _GENERATED_AT.sub(b"", content)
            digest.update(f"{name}\n{len(content)}\n".encode())
            digest.update(content)
    return digest.hexdigest()


def flown_from(campaign: Campaign, plant_fmu: bytes, controller_fmu: bytes | None) -> dict:
    """What decides a row, as plain JSON values."""
    return {
        "seed": campaign.seed,
        "duration": campaign.duration,
        "step": campaign.step,
        "controller": campaign.controller,
        "system": campaign.system.name if campaign.system else None,
        "end_effector": campaign.end_effector,
        "wrench_bodies": list(campaign.wrench_bodies),
        "settle_threshold": campaign.settle_threshold,
        "trajectories": campaign.trajectories,
        "metrics": list(campaign.metrics),
        "plant": dict(campaign.plant_parameters),
        "controller parameters": dict(campaign.controller_parameters),
        "dispersions": {d.key: {d.distribution: list(d.parameters)} for d in campaign.dispersions},
        "schedules": {name: [list(point) for point in points] for name, points in campaign.schedules.items()},
        "plant FMU": fmu_hash(plant_fmu),
        "controller FMU": fmu_hash(controller_fmu) if controller_fmu is not None else None,
    }


def _show(value) -> str:
    if value is None:
        return "none"
    if isinstance(value, str) and re.fullmatch(r"[0-9a-f]{64}", value):
        return value[:12]
    return json.dumps(value, separators=(", ", ": "))


def differences(old: dict, new: dict) -> list[str]:
    """'key: old → new' for each entry that differs (a section's entries one by one)."""
    lines = []
    for key in dict.fromkeys([*old, *new]):
        before, after = old.get(key), new.get(key)
        if before == after:
            continue
        if isinstance(before, dict) and isinstance(after, dict):
            for entry in dict.fromkeys([*before, *after]):
                if before.get(entry) != after.get(entry):
                    lines.append(f"{key}.{entry}: {_show(before.get(entry))} → {_show(after.get(entry))}")
        else:
            lines.append(f"{key}: {_show(before)} → {_show(after)}")
    return lines


def rows_written(out: Path) -> list[Path]:
    """The rows and trajectories already in OUT."""
    return sorted((out / "parts").glob("part-*.parquet")) + sorted((out / "trajectories").glob("case-*.parquet"))


def replaced_files(campaign: Campaign, out: Path) -> list[Path]:
    """The files of OUT a run writes over besides its rows: the results, the
    report and its plots, the FMUs."""
    from .report import grid_plot_name

    names = ["results.parquet", "report.md", "metrics.png", "fmus/plant.fmu", "fmus/controller.fmu"]
    names += [grid_plot_name(d.key) for d in campaign.dispersions if d.distribution == "grid"]
    return [out / name for name in names]


def resume_or_start(out: Path, record: dict, overwrite: bool, replaced: list[Path] = ()) -> None:
    """Keeps OUT's rows if they were flown from `record`; removes them
    (`overwrite`) or refuses if not; refuses to write over the files
    `replaced` in an OUT with no record, since no campaign wrote them (the
    user's own report.md), unless `overwrite`; then writes the record."""
    written = rows_written(out)
    foreign = [path for path in replaced if os.path.lexists(path)] if not (out / RECORD).exists() else []
    if foreign and not written and not overwrite:
        names = ", ".join(str(path.relative_to(out)) for path in foreign)
        raise CampaignError(
            f"{out} holds {names} and no {RECORD}: no campaign wrote them, and this one would replace them; "
            "rerun with --overwrite to replace them, or choose another --out"
        )
    if written and not overwrite:
        path = out / RECORD
        try:
            old = json.loads(path.read_text())["flown_from"]
        except FileNotFoundError:
            raise CampaignError(
                f"{out} holds {len(written)} file(s) of rows with no record of what they were flown from "
                f"({path} is missing): rerun with --overwrite to remove them and start afresh, or choose another --out"
            ) from None
        except (OSError, ValueError, KeyError, TypeError) as error:
            raise CampaignError(f"{path}: cannot be read ({error}): rerun with --overwrite to start afresh") from None
        changed = differences(old, record)
        if changed:
            raise CampaignError(
                f"{out} holds the rows of another campaign ({'; '.join(changed)}): rerun with --overwrite "
                "to remove them and start afresh, or choose another --out"
            )
    if overwrite:
        for path in [*written, out / "results.parquet", out / "report.md", out / "metrics.png"]:
            if path.is_file() or path.is_symlink():
                path.unlink()
    write_atomically(out / RECORD, lambda temporary: temporary.write_text(json.dumps({"flown_from": record}, indent=1)))
