"""Whether a campaign's targets name variables that its FMUs have and
that can take the values given, checked against the exported FMUs before
any case flies: a campaign that could only fail in every case (theta[99] on
a vehicle with nq = 14, names on a number) is refused with the key."""

from __future__ import annotations

from nudyn_driver.package import FmuPackage

from .spec import Campaign, CampaignError

# Start values the FMU takes before initialization although they are outputs.
STARTS = ("theta", "nu")


def _has(scope: str, package: FmuPackage, name: str) -> str:
    """Why the `scope` FMU `package` cannot set `name` ("" when it can)."""
    base = name.partition("[")[0]
    if name not in package.variables:
        entries = package.names(base)
        if entries and "[" not in name:
            return ""  # an array parameter without an index sets every entry
        if entries:
            return f"the {scope} FMU has {entries[0]} to {entries[-1]} only"
        return f"the {scope} FMU has no variable '{name}'"
    variable = package.variables[name]
    if variable.causality not in ("parameter", "input") and base not in STARTS:
        return f"the {scope} FMU computes '{name}' (an {variable.causality}); it cannot be set"
    return ""


def _takes(scope: str, package: FmuPackage, name: str, values: tuple) -> str:
    """Why `name` of the `scope` FMU cannot take `values` ("" when it can)."""
    variable = package.variables.get(name) or package.variables[package.names(name)[0]]
    names = [v for v in values if isinstance(v, str)]
    if variable.type == "Enumeration" and names:
        items = package.enumeration_items(variable.name)
        unknown = [v for v in names if v not in items]
        return f"the {scope} FMU has no {name} '{unknown[0]}' (it has {', '.join(items)})" if unknown else ""
    if names:
        return f"{scope} variable '{name}' takes a number ({variable.type}), not the names {', '.join(map(repr, names))}"
    return ""


def check(campaign: Campaign, plant: FmuPackage, controller: FmuPackage | None) -> None:
    """Refuses the first target the FMUs cannot take, with its key."""
    packages = {"plant": plant, "controller": controller}
    for dispersion in campaign.dispersions:
        package = packages[dispersion.scope]
        for name in dispersion.names:
            if name.startswith("qvel["):
                index = int(name[5:-1])
                why = "" if index <= plant.nv else f"the plant FMU has qvel[1] to qvel[{plant.nv}] only (nv = {plant.nv})"
            else:
                scope = dispersion.scope
                why = _has(scope, package, name) or _takes(scope, package, name, dispersion.parameters)
            if why:
                raise CampaignError(f"dispersions.{dispersion.key}: {why}")
    fixed = [("plant", plant, campaign.plant_parameters), ("controller", controller, campaign.controller_parameters)]
    for scope, package, values in fixed:
        for name, value in values.items():
            if package is None:
                raise CampaignError(f"{scope}.{name}: [{scope}] needs campaign.controller = true")
            why = _has(scope, package, name) or _takes(scope, package, name, (value,))
            if why:
                raise CampaignError(f"{scope}.{name}: {why}")
    for name in campaign.schedules:
        why = _has("plant", plant, name)
        if why:
            raise CampaignError(f"schedules.{name}: {why}")
