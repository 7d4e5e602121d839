"""A strict grammar of the KUKA KRL that `remaster program` writes: a check of a .src program's text
that is not remaster's own reader (`programs.parse_program` reads moves and skips what it does not
know; this refuses it).

The subset, one statement a line, keywords in any case (KRL's), names compared in any case:

    program   := attribute* blank* DEF <name>() line* END blank*
    attribute := &ACCESS <letters> | &REL <digits>            (before DEF only)
    line      := blank | statement [; comment]
    statement := $VEL_AXIS[i] = <number> | $ACC_AXIS[i] = <number>        (i in 1..6)
               | $VEL_EXTAX[i] = <number> | $ACC_EXTAX[i] = <number>      (i in 1..6)
               | PTP {<axis> <number>, ...}   (A1..A6 each once, E1 at most once, nothing else)
               | WAIT SEC <number>
    blank     := whitespace only, or a comment: ; anything

A <name> is a letter or _, then letters, digits or _, at most 24 characters; a <number> an integer
or decimal with an optional sign and exponent. `check_krl` returns the number of PTP moves, or
raises InputError naming the source and the 1-based line of the first statement outside the subset
(an ENDX, a brace never closed, a missing END, a DEF not named as its file, an axis other than
A1..A6 and E1, a value that is not a number).
"""

from __future__ import annotations

import re

from ..errors import InputError, quoted

NAME = r"[A-Za-z_][A-Za-z0-9_]{0,23}"
NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
ROBOT_AXES = tuple(f"A{j}" for j in range(1, 7))
EXTERNAL_AXES = ("E1",)

_ATTRIBUTE = re.compile(r"&ACCESS\s+[A-Z]+|&REL\s+\d+", re.I)
_DEF = re.compile(rf"DEF\s+({NAME})\s*\(\s*\)", re.I)
_END = re.compile(r"END", re.I)
_SYSTEM_VARIABLE = re.compile(r"\$(VEL_AXIS|ACC_AXIS|VEL_EXTAX|ACC_EXTAX)\s*\[\s*(\d+)\s*\]\s*=\s*(\S.*)", re.I)
_PTP = re.compile(r"PTP\s*\{(.*)\}", re.I)
_WAIT = re.compile(r"WAIT\s+SEC\s+(\S.*)", re.I)
_AXIS_VALUE = re.compile(r"([A-Za-z_$][A-Za-z0-9_$]*)\s+(\S.*)")


def _statement(text: str) -> str:
    """A line without its comment (KRL's `;` to the end of the line; this subset has no strings) and outer blanks."""
    return text.split(";", 1)[0].strip()


def _number(text: str, what: str, where: str, source: str) -> float:
    if not re.fullmatch(NUMBER, text.strip()):
        raise InputError(f"{where}: {what} is not a number: {quoted(text.strip())}", file=source)
    return float(text)


def _ptp(inside: str, where: str, source: str) -> None:
    seen: list[str] = []
    for item in inside.split(","):
        match = _AXIS_VALUE.fullmatch(item.strip())
        if not match:
            raise InputError(f"{where}: not an axis and its value: {quoted(item.strip())}", file=source)
        axis = match.group(1).upper()
        if axis not in ROBOT_AXES + EXTERNAL_AXES:
            raise InputError(
                f"{where}: unknown axis {match.group(1)!r}: one of {', '.join(ROBOT_AXES + EXTERNAL_AXES)}", file=source
            )
        if axis in seen:
            raise InputError(f"{where}: axis {axis} given twice", file=source)
        _number(match.group(2), f"the value of {axis}", where, source)
        seen.append(axis)
    missing = [a for a in ROBOT_AXES if a not in seen]
    if missing:
        raise InputError(
            f"{where}: a PTP of this subset gives every robot axis: {', '.join(missing)} missing", file=source
        )


def _body_statement(statement: str, where: str, source: str) -> bool:
    """Check one statement between DEF and END; True for a PTP move."""
    if statement.count("{") != statement.count("}") or statement.find("}") < statement.find("{"):
        raise InputError(f"{where}: unbalanced braces: {quoted(statement)}", file=source)
    if match := _SYSTEM_VARIABLE.fullmatch(statement):
        index = int(match.group(2))
        if not 1 <= index <= 6:
            raise InputError(f"{where}: ${match.group(1).upper()}[{index}]: the index is 1..6", file=source)
        _number(match.group(3), f"${match.group(1).upper()}[{index}]", where, source)
        return False
    if match := _PTP.fullmatch(statement):
        _ptp(match.group(1), where, source)
        return True
    if match := _WAIT.fullmatch(statement):
        _number(match.group(1), "WAIT SEC's time", where, source)
        return False
    raise InputError(f"{where}: not a statement remaster's KRL has: {quoted(statement)}", file=source)


def check_krl(text: str, name: str | None = None, source: str = "program") -> int:
    """The number of PTP moves of the KRL program `text` in the subset above; its DEF must be named
    `name` (the file's stem) when given. InputError naming `source` and the line otherwise."""
    definition = None  # (line, name) of the DEF once read
    ended = False
    moves = 0
    lines = text.splitlines()
    for number, line in enumerate(lines, start=1):
        where = f"line {number}"
        statement = _statement(line)
        if not statement:
            continue
        if ended:
            raise InputError(f"{where}: after the END of DEF {definition[1]}(): {quoted(statement)}", file=source)
        if definition is None:
            if _ATTRIBUTE.fullmatch(statement):
                continue
            match = _DEF.fullmatch(statement)
            if not match:
                raise InputError(
                    f"{where}: expected DEF <name>() (or an &ACCESS line), got {quoted(statement)}", file=source
                )
            if name is not None and match.group(1).lower() != name.lower():
                raise InputError(
                    f"{where}: DEF {match.group(1)}() in a program named {name!r}: KRL names a DEF as its file",
                    file=source,
                )
            definition = (number, match.group(1))
        elif _END.fullmatch(statement):
            ended = True
        else:
            moves += _body_statement(statement, where, source)
    if definition is None:
        raise InputError("no DEF <name>() line: not a KRL program", file=source)
    if not ended:
        raise InputError(
            f"line {len(lines)}: the program ends without the END of DEF {definition[1]}() (line {definition[0]})",
            file=source,
        )
    return moves
