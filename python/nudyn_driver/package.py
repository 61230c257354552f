"""An exported FMU unzipped once: what its modelDescription.xml says about
each variable, read with the standard library alone. The misuse tests read
it in one fresh process per case, where importing FMPy (and numpy) would
take several times as long as the case itself."""

from __future__ import annotations

import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass
from pathlib import Path

from .errors import DriverError


@dataclass(frozen=True)
class Variable:
    name: str
    value_reference: int  # unique per type only (FMI 2.0)
    type: str  # "Real", "Integer", "Boolean", "String" or "Enumeration"
    causality: str
    start: str | None  # as written in the model description
    declared_type: str | None  # the SimpleType an Enumeration takes its items from


class FmuPackage:
    """An unzipped FMU (a plant's or a controller's): its variables by name,
    their value references, nq and nv, and the items of its `method`
    enumeration (none for a controller). Instances are made from it."""

    def __init__(self, directory: Path):
        self.directory = Path(directory)
        root = ET.parse(self.directory / "modelDescription.xml").getroot()
        self.guid = root.get("guid")
        self.model_identifier = root.find("CoSimulation").get("modelIdentifier")
        # SimpleType name → (its description, its items by name).
        self._types: dict[str, tuple[str, dict[str, int]]] = {}
        for simple_type in root.iterfind("TypeDefinitions/SimpleType"):
            items = {item.get("name"): int(item.get("value")) for item in simple_type.iterfind("Enumeration/Item")}
            self._types[simple_type.get("name")] = (simple_type.get("description") or simple_type.get("name"), items)
        self.variables: dict[str, Variable] = {}
        for scalar in root.iterfind("ModelVariables/ScalarVariable"):
            kind = scalar[0]
            self.variables[scalar.get("name")] = Variable(
                name=scalar.get("name"),
                value_reference=int(scalar.get("valueReference")),
                type=kind.tag,
                causality=scalar.get("causality", "local"),
                start=kind.get("start"),
                declared_type=kind.get("declaredType"),
            )
        self.vr = {name: v.value_reference for name, v in self.variables.items()}
        # The array variables (theta[1], theta[2], ...) by prefix, in index order.
        self._arrays: dict[str, list[str]] = {}
        for name in self.variables:
            prefix, bracket, _ = name.partition("[")
            if bracket:
                self._arrays.setdefault(prefix, []).append(name)
        self.nq = len(self.names("theta"))
        self.nv = len(self.names("nu"))
        self.methods = self.enumeration_items("method") if "method" in self.variables else {}

    @classmethod
    def unzip(cls, fmu: Path, directory: Path) -> FmuPackage:
        """The FMU at `fmu`, extracted into `directory`."""
        with zipfile.ZipFile(fmu) as archive:
            archive.extractall(directory)
        return cls(directory)

    @property
    def reals(self) -> list[str]:
        """The names of every Real variable, in the model description's order."""
        return [name for name, v in self.variables.items() if v.type == "Real"]

    def names(self, prefix: str) -> list[str]:
        """prefix[1], prefix[2], ...: the names of one array variable."""
        return self._arrays.get(prefix, [])

    def refs(self, prefix: str) -> list[int]:
        return [self.vr[name] for name in self.names(prefix)]

    def starts(self, prefix: str) -> list[float]:
        """The start values of the Real array variable prefix[1..]."""
        return [float(self.variables[name].start) for name in self.names(prefix)]

    def parameters(self, type_name: str) -> list[str]:
        """The names of the parameters of one type ("Real", "Boolean", ...)."""
        return [name for name, v in self.variables.items() if v.causality == "parameter" and v.type == type_name]

    def variable(self, name: str) -> Variable:
        if name not in self.variables:
            raise DriverError(f"the FMU has no variable '{name}'")
        return self.variables[name]

    def enumeration_items(self, name: str) -> dict[str, int]:
        """The items of the Enumeration variable `name`, by item name."""
        return self._types[self.variable(name).declared_type][1]

    def enumeration_value(self, name: str, item: str) -> int:
        """The value of the item called `item` of the Enumeration variable `name`."""
        what, items = self._types[self.variable(name).declared_type]
        if item not in items:
            raise DriverError(f"the FMU has no {what} '{item}' (it has: {', '.join(items)})")
        return items[item]
