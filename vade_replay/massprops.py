"""Mass properties: the CAD report parser and the checks every source goes through.

A Creo / Pro/ENGINEER mass-property report (``NAME.m_p``) is plain text. The parts
read here are::

    MASS = 2.0000000e-01 KILOGRAM
    CENTER OF GRAVITY with respect to _PRT0001 coordinate frame:
    X  Y  Z   1.0000000e+01  0.0000000e+00  5.0000000e+00  MM
    INERTIA at CENTER OF GRAVITY with respect to _PRT0001 coordinate frame:  (KILOGRAM * MM^2)
    INERTIA TENSOR:
    Ixx Ixy Ixz  ...
    Iyx Iyy Iyz  ...
    Izx Izy Izz  ...

Creo prints the inertia *tensor*, whose off-diagonal entries are the negated products of
inertia (``Ixy = -integral(x y dm)``); ``products_sign="products"`` reads a report whose
off-diagonal entries are the products themselves and negates them. The units come from the
report's own unit words and are converted to kg and metres once, here.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from . import spatial as sp
from .errors import SessionError

LENGTH_TO_M = {"M": 1.0, "METER": 1.0, "MM": 1e-3, "MILLIMETER": 1e-3, "CM": 1e-2,
               "IN": 0.0254, "INCH": 0.0254, "FT": 0.3048, "FOOT": 0.3048}
MASS_TO_KG = {"KILOGRAM": 1.0, "KG": 1.0, "GRAM": 1e-3, "G": 1e-3, "TONNE": 1e3,
              "POUND": 0.45359237, "LBM": 0.45359237, "LB": 0.45359237}

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


@dataclass(frozen=True, slots=True)
class MassProperties:
    """Mass (kg), centre of mass (m) and inertia tensor at the CM (kg m^2), in the part frame."""

    mass_kg: float
    center_of_mass: tuple[float, float, float]
    inertia_cm: tuple[tuple[float, float, float], ...]


def check(props: MassProperties, *, file: str | None, field: str) -> MassProperties:
    """Reject mass properties no rigid body can have: these would silently corrupt dynamics."""
    values = [props.mass_kg, *props.center_of_mass, *(x for row in props.inertia_cm for x in row)]
    if not all(math.isfinite(v) for v in values):
        raise SessionError("mass properties hold a non-finite number", file=file, field=field)
    if props.mass_kg <= 0.0:
        raise SessionError(f"mass must be positive, got {props.mass_kg}", file=file, field=field)
    inertia = props.inertia_cm
    for i in range(3):
        for j in range(3):
            if abs(inertia[i][j] - inertia[j][i]) > 1e-9 * max(1e-30, abs(inertia[i][i])):
                raise SessionError("inertia tensor is not symmetric", file=file, field=field)
    # The principal moments of a rigid body are positive and each at most the sum of the
    # other two (equality only for a flat body).
    a, b, c = sp.symmetric_eigen(inertia)[0]
    slack = 1e-9 * (abs(a) + abs(b) + abs(c))
    # (Finite entries near float64's top can still give an infinite moment.)
    if not math.isfinite(a + b + c) or a <= 0.0 or c > a + b + slack:
        raise SessionError(
            f"inertia tensor has principal moments {a:.6g}, {b:.6g}, {c:.6g} kg m^2 (in SI, "
            "whatever the file's units): not a rigid body's (each must be positive and at "
            "most the sum of the other two)",
            file=file, field=field)
    return props


def _unit_factor(table: dict[str, float], word: str, *, file: str, field: str) -> float:
    key = word.strip().upper()
    if key not in table:
        raise SessionError(f"unknown unit {word!r}", file=file, field=field)
    return table[key]


def parse_creo_report(text: str, *, file: str = "<report>",
                      products_sign: str = "tensor") -> MassProperties:
    """Parse a Creo / Pro/ENGINEER ``.m_p`` mass-property report into SI units."""
    if products_sign not in ("tensor", "products"):
        raise SessionError(f"products_sign must be 'tensor' or 'products', got {products_sign!r}",
                           file=file, field="products_sign")
    lines = text.splitlines()

    mass_match = re.search(rf"^\s*MASS\s*=\s*({_NUMBER})\s*([A-Za-z]+)", text, re.MULTILINE)
    if not mass_match:
        raise SessionError("no 'MASS = <value> <unit>' line", file=file, field="MASS")
    mass_kg = float(mass_match.group(1)) * _unit_factor(MASS_TO_KG, mass_match.group(2),
                                                        file=file, field="MASS")

    cog_line = None
    for index, line in enumerate(lines):
        if line.strip().upper().startswith("CENTER OF GRAVITY"):
            cog_line = index
            break
    if cog_line is None:
        raise SessionError("no CENTER OF GRAVITY section", file=file, field="CENTER OF GRAVITY")
    cog_match = None
    for line in lines[cog_line + 1: cog_line + 4]:
        cog_match = re.match(rf"\s*X\s+Y\s+Z\s+({_NUMBER})\s+({_NUMBER})\s+({_NUMBER})\s+([A-Za-z]+)",
                             line)
        if cog_match:
            break
    if not cog_match:
        raise SessionError("CENTER OF GRAVITY has no 'X Y Z <x> <y> <z> <unit>' line",
                           file=file, field="CENTER OF GRAVITY")
    length = _unit_factor(LENGTH_TO_M, cog_match.group(4), file=file, field="CENTER OF GRAVITY")
    com = tuple(float(cog_match.group(i)) * length for i in (1, 2, 3))

    header = None
    for index, line in enumerate(lines):
        if re.match(r"\s*INERTIA\s+at\s+CENTER\s+OF\s+GRAVITY", line, re.IGNORECASE):
            header = index
            break
    if header is None:
        raise SessionError("no 'INERTIA at CENTER OF GRAVITY' section", file=file,
                           field="INERTIA at CENTER OF GRAVITY")
    unit_match = re.search(r"\(\s*([A-Za-z]+)\s*\*\s*([A-Za-z]+)\s*\^\s*2\s*\)", lines[header])
    if not unit_match:
        raise SessionError("INERTIA at CENTER OF GRAVITY has no '(MASS * LENGTH^2)' unit",
                           file=file, field="INERTIA at CENTER OF GRAVITY")
    inertia_factor = (_unit_factor(MASS_TO_KG, unit_match.group(1), file=file, field="INERTIA")
                      * _unit_factor(LENGTH_TO_M, unit_match.group(2), file=file,
                                     field="INERTIA") ** 2)
    rows = []
    for line in lines[header + 1:]:
        row = re.match(rf"\s*I([xyz])([xyz])\s+I[xyz][xyz]\s+I[xyz][xyz]\s+({_NUMBER})\s+({_NUMBER})"
                       rf"\s+({_NUMBER})", line)
        if row:
            rows.append(tuple(float(row.group(i)) * inertia_factor for i in (3, 4, 5)))
            if len(rows) == 3:
                break
    if len(rows) != 3:
        raise SessionError("INERTIA at CENTER OF GRAVITY has no three 'Ixx Ixy Ixz ...' rows",
                           file=file, field="INERTIA at CENTER OF GRAVITY")
    if products_sign == "products":
        rows = [tuple(v if i == j else -v for j, v in enumerate(row)) for i, row in enumerate(rows)]
    props = MassProperties(mass_kg, com, tuple(rows))  # type: ignore[arg-type]
    return check(props, file=file, field="INERTIA at CENTER OF GRAVITY")
