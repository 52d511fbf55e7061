"""Position names a controller accepts, as close to the operator's as its rules allow.

The neutral program carries the operator's names (P7, Pick_left, approach 1). Each dialect
derives its identifiers from them (MELFA `P`/`J` prefixes in capitals, KRL `X` prefix,
URScript `<name>_q` joint lists) and controllers limit length and characters (MELFA BASIC
IV: 8 characters). A name every derived identifier of which is legal and unique (controllers
mostly ignore case) is kept as it is; any other is renamed to the closest legal form -
illegal characters dropped, shortened, a number appended to stay unique - and the rename is
reported once, in the export's notes, so the operator finds "Pick_left" again as "PPICKLEF"
on the teach pendant.
"""

from __future__ import annotations

import re
from collections.abc import Callable

from assistant.export.errors import ExportError
from assistant.export.program import NeutralProgram, renamed
from assistant.export.rules import DialectRules, check_identifier

#: Identifiers a dialect derives from a position name (pose or joint target); all must be
#: legal and unique.
Derive = Callable[[str, bool], tuple[str, ...]]


def identity(name: str, joint_target: bool = False) -> tuple[str, ...]:
    return (name,)


def legal_names(program: NeutralProgram, rules: DialectRules, derive: Derive = identity,
                ) -> tuple[NeutralProgram, tuple[str, ...]]:
    """The program with every position name legal for `rules`, and one note per rename.

    Names legal as they are are kept first (a rename never takes another position's name);
    the others get the closest legal, unused form."""
    positions = program.positions()
    taken: set[str] = set()
    mapping: dict[str, str] = {}
    why: dict[str, str] = {}
    for p in positions:
        problem = _problem(p.name, p.joint_target, rules, derive, taken)
        if problem is None:
            mapping[p.name] = p.name
            taken |= {_key(i, rules) for i in derive(p.name, p.joint_target)}
        else:
            why[p.name] = problem
    notes: list[str] = []
    for p in positions:
        if p.name in mapping:
            continue
        new = _legal_form(p.name, p.joint_target, rules, derive, taken)
        taken |= {_key(i, rules) for i in derive(new, p.joint_target)}
        mapping[p.name] = new
        notes.append(f"position {p.name} is written as {derive(new, p.joint_target)[0]}: "
                     f"{why[p.name]}")
    if not notes:
        return program, ()
    return renamed(program, mapping), tuple(notes)


def legal_for(program: NeutralProgram, dialect) -> tuple[NeutralProgram, tuple[str, ...]]:
    """`legal_names` with the dialect's rules and its `position_identifiers` (if it has
    them): what `export_files` and `round_trip` write."""
    return legal_names(program, dialect.rules,
                       getattr(dialect, "position_identifiers", identity))


def _key(ident: str, rules: DialectRules) -> str:
    return ident if rules.case_sensitive else ident.upper()


def _problem(name: str, joint_target: bool, rules: DialectRules, derive: Derive,
             taken: set[str]) -> str | None:
    """Why `name` cannot be used as it is (None: it can)."""
    for ident in derive(name, joint_target):
        try:
            check_identifier(ident, rules, what="position")
        except ExportError as exc:
            return _short_reason(str(exc), rules)
        if _key(ident, rules) in taken:
            return (f"{ident} is taken by another position" + (
                "" if rules.case_sensitive else " (names are not case-sensitive)"))
    return None


def _short_reason(message: str, rules: DialectRules) -> str:
    """The rule from a `check_identifier` message, without the dialect prefix."""
    text = message.split(": ", 1)[-1] if message.startswith(rules.dialect) else message
    return re.sub(r"^position ", "", text)


def _legal_form(name: str, joint_target: bool, rules: DialectRules, derive: Derive,
                taken: set[str]) -> str:
    """The closest legal, unused name: illegal characters dropped (then underscores),
    shortened, numbered."""
    word = re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9_]", "", name)).strip("_") or "P"
    if not word[0].isalpha():
        word = "P" + word
    # dropping underscores keeps every letter; shortening comes after
    forms = [word.replace("_", ""), word] if "_" in word else [word]
    for k in range(0, 1000):
        suffix = "" if k == 0 else str(k)
        for w in forms:
            # the longest derived identifier decides how long the name may be
            extra = max(len(i) for i in derive(w, joint_target)) - len(w)
            room = max(1, rules.max_identifier - extra)
            cand = w[: max(1, room - len(suffix))].rstrip("_") + suffix
            if _problem(cand, joint_target, rules, derive, taken) is None:
                return cand
    raise ExportError(f"no legal {rules.dialect} name found for position {name!r}")
