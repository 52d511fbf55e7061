"""Controller rules every dialect enforces: identifiers, number format, line length, file size.

Controllers reject over-long or illegal names and lines, and an exponent or a "-0.000" in a
position makes a program look machine-made (or fails to parse). The rules are data per
dialect (`DialectRules`), the checks are free functions, so a test can hand a dialect tighter
limits (e.g. 3 positions per file) and see the split happen.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

from assistant.export.errors import ExportError

#: Largest magnitude written: 100 km in mm. Anything larger is a unit mistake, not a position.
MAX_ABS_VALUE = 1.0e8


@dataclass(frozen=True)
class DialectRules:
    """What one controller accepts. Limits that are not documented are conservative guesses
    and configurable (`with_limits`)."""

    dialect: str
    identifier: re.Pattern[str]
    identifier_hint: str
    max_identifier: int
    max_line: int
    #: Positions declared in one program file; more are split into parts called by a main.
    max_positions_per_file: int | None
    reserved: frozenset[str] = field(default_factory=frozenset)
    case_sensitive: bool = False
    #: Program (module) names may be stricter than variable names.
    program_identifier: re.Pattern[str] | None = None
    program_hint: str = ""
    max_program_name: int | None = None

    def with_limits(self, **changes) -> DialectRules:
        return replace(self, **changes)

    def is_reserved(self, name: str) -> bool:
        key = name if self.case_sensitive else name.upper()
        return key in self.reserved


def format_fixed(value: float, decimals: int, *, plus: bool = False, what: str = "value",
                 step: str = "") -> str:
    """Fixed-point text with exactly `decimals` decimals: never an exponent, never "-0.00".

    `plus` writes an explicit "+" (MELFA's position style). Non-finite or absurd values raise,
    they are bugs upstream and must not reach a controller.
    """
    v = float(value)
    if not math.isfinite(v) or abs(v) > MAX_ABS_VALUE:
        raise ExportError(f"{what} = {v!r} cannot be written as a number", step=step)
    text = f"{v:.{decimals}f}"
    if text.lstrip("-").strip("0.") == "":  # rounds to zero: drop the sign
        text = text.lstrip("-")
    if plus and not text.startswith("-"):
        text = "+" + text
    return text


def euler_deg(angles_rad: Sequence[float], decimals: int) -> list[float]:
    """Euler angles in degrees as one orientation is always written: an angle that would
    read -180 at `decimals` is written +180 (the same turn). Near a half turn the angle's
    sign follows the last bits of the rotation matrix, which differ between processors and
    between a typed and a measured pose; the program text must not."""
    out = []
    for a in angles_rad:
        d = math.degrees(float(a))
        out.append(d + 360.0 if round(d, decimals) <= -180.0 else d)
    return out


def half_turn_sign(v: Sequence[float], decimals: int, *, skip: int = 0) -> list[float]:
    """A quaternion (w first, `skip` = 1) or a rotation vector whose sign is free - w = 0, or
    a turn of pi - written with its first component that shows at `decimals` positive, so
    the same orientation always gives the same text."""
    vals = [float(x) for x in v]
    lead = next((x for x in vals[skip:] if round(abs(x), decimals) > 0.0), 0.0)
    return [-x for x in vals] if lead < 0.0 else vals


def format_compact(value: float, max_decimals: int = 3, *, what: str = "value",
                   step: str = "") -> str:
    """Settings (speeds, overrides, waits) as a person types them: "50", "12.5", "0.25"."""
    text = format_fixed(value, max_decimals, what=what, step=step)
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def parse_number(text: str) -> float:
    """Inverse of the formatters (also accepts RAPID's 9E+09 placeholder)."""
    return float(text.strip().replace(" ", ""))


def check_identifier(name: str, rules: DialectRules, *, what: str, step: str = "",
                     program: bool = False) -> str:
    """Return `name` if the controller accepts it as an identifier, else raise naming why."""
    pattern = rules.program_identifier if program and rules.program_identifier else (
        rules.identifier)
    hint = rules.program_hint if program and rules.program_hint else rules.identifier_hint
    limit = rules.max_program_name if program and rules.max_program_name else (
        rules.max_identifier)
    if not name:
        raise ExportError(f"{what} has no name", step=step, dialect=rules.dialect)
    if len(name) > limit:
        raise ExportError(f"{what} {name!r} is {len(name)} characters long; {rules.dialect} "
                          f"allows at most {limit}", step=step, dialect=rules.dialect)
    if not pattern.fullmatch(name):
        raise ExportError(f"{what} {name!r} is not a legal {rules.dialect} name ({hint})",
                          step=step, dialect=rules.dialect)
    if rules.is_reserved(name):
        raise ExportError(f"{what} {name!r} is a reserved word in {rules.dialect}", step=step,
                          dialect=rules.dialect)
    return name


def check_lines(text: str, rules: DialectRules, filename: str) -> None:
    """Every line within the controller's limit; an exponent in a number is a bug here."""
    for k, line in enumerate(text.splitlines(), start=1):
        if len(line) > rules.max_line:
            raise ExportError(f"{filename} line {k} is {len(line)} characters long; "
                              f"{rules.dialect} allows at most {rules.max_line}",
                              dialect=rules.dialect)
        if _EXPONENT.search(_strip_known_tokens(line)):
            raise ExportError(f"{filename} line {k} contains a number with an exponent: "
                              f"{line.strip()!r}", dialect=rules.dialect)


# A number with an exponent: 1e-05, 2.5E+03 (but not names like P1E5 or D12E3).
_EXPONENT = re.compile(r"(?<![A-Za-z0-9_.])\d+(\.\d*)?[eE][+-]?\d+")


def _strip_known_tokens(line: str) -> str:
    # RAPID marks unused external axes with the literal 9E+09: a convention, not a value.
    return line.replace("9E+09", "")
