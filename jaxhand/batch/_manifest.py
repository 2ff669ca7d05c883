"""Batch manifests: one job per row (CSV) or per ``[[jobs]]`` table (TOML), validated whole.

A job is one ``jaxhand track`` or ``jaxhand fit-landmarks`` call. Its keys are the command's own
options without the dashes (``model``, ``camera``, ``init``, ``max_frames`` or ``max-frames``,
``no_video = true``), its positional arguments by name (``inputs`` for ``track``; ``inputs`` also
fills the single positional argument of a command that names it otherwise, such as the landmark
file of ``fit-landmarks``), plus ``name`` (the job's output folder under the batch's ``--out``)
and ``command``. ``--out`` itself is set by the batch.

The options are checked against the command's own parser (``jaxhand.cli.build_parser``), so the
manifest accepts exactly what the single command accepts, and every job's arguments are parsed
once here, before any job starts: a bad manifest fails as a whole with one line naming the row
and the column (and a "did you mean" for a misspelt key).

Shared defaults: the TOML ``[defaults]`` table; in a CSV, a first data row whose ``name`` is
``*``. Empty CSV cells take the default. A default applies to every job whose command has that
option (a ``track``-only option is left out of ``fit-landmarks`` jobs); a default that no job's
command accepts is an error. Several values in one CSV cell (several inputs, ``camera`` once per
camera) are separated by ``;``; TOML takes lists.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import difflib
import io
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

from .._errors import InputError

__all__ = ["Job", "Manifest", "load_manifest", "parse_manifest", "COMMANDS", "MANIFEST_VERSION"]

#: The commands a batch can run; each writes ``summary.json`` into its ``--out`` when it finishes.
COMMANDS = ("track", "fit-landmarks")
#: The TOML manifest's ``format_version``.
MANIFEST_VERSION = 1
#: Keys every job has besides its command's options.
_FIELDS = ("name", "command")
#: Options the batch sets itself.
_RESERVED = {"out": "set by jaxhand batch to DIR/<name>", "help": "not an option of a batch job"}
#: The files a batch writes next to the job folders (job names must not clash with them).
_RESERVED_NAMES = ("batch_summary.csv", "batch_summary.json", "batch_summary.png")
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*\Z")
_TRUE, _FALSE = ("true", "yes", "1", "on"), ("false", "no", "0", "off", "")


@dataclass(frozen=True)
class Job:
    """One validated job.

    Attributes:
        name: the job's output folder under the batch's ``--out``.
        command: ``track`` or ``fit-landmarks``.
        args: the command's arguments (``[command, positionals..., options...]``) without ``--out``.
        where: the manifest row it comes from, for messages (``jobs.csv line 4``).
    """

    name: str
    command: str
    args: tuple[str, ...]
    where: str

    def argv(self, out_dir: str | Path) -> list[str]:
        """The ``jaxhand`` argument list of this job writing into ``out_dir / name``."""
        return [*self.args, "--out", str(Path(out_dir) / self.name)]


@dataclass(frozen=True)
class Manifest:
    """A validated manifest: its jobs in order."""

    path: Path
    jobs: tuple[Job, ...]


def load_manifest(path: str | Path) -> Manifest:
    """Read and validate a ``.csv`` or ``.toml`` manifest (see the module docstring).

    Raises:
        InputError: one line naming the file, the row and the column of the first problem.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as err:
        raise InputError(f"{path}: cannot read the manifest ({err.strerror})") from err
    return parse_manifest(text, path)


def parse_manifest(text: str, path: str | Path) -> Manifest:
    """:func:`load_manifest` on ``text``; ``path`` names the file in messages and gives its format
    by its suffix (``.csv`` or ``.toml``)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".toml":
        defaults, rows = _read_toml(text, path)
    elif suffix == ".csv":
        defaults, rows = _read_csv(text, path)
    else:
        raise InputError(f"{path}: expected a .csv or .toml manifest, got {path.suffix or 'no suffix'!r}")
    if not rows:
        raise InputError(f"{path}: no jobs")
    parsers = _command_parsers()
    jobs, seen, used_defaults = [], {}, set()
    for where, row in rows:
        job, used = _job(path, where, defaults, row, parsers)
        if job.name in seen:
            raise InputError(f"{path}: {where}, column 'name': job name {job.name!r} is already used at "
                             f"{seen[job.name]}")
        seen[job.name] = where
        used_defaults |= used
        jobs.append(job)
    for key in defaults:
        if _norm(key) not in used_defaults and _norm(key) not in _FIELDS:
            known = sorted({k for p in parsers.values() for k in _option_keys(p)})
            raise InputError(f"{path}: defaults, column {key!r}: not an option of any job's command"
                             f"{_did_you_mean(key, known)}")
    return Manifest(path, tuple(jobs))


def _norm(key: str) -> str:
    return key.strip().replace("_", "-")


def _did_you_mean(key: str, known) -> str:
    close = difflib.get_close_matches(_norm(key), list(known), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _read_toml(text: str, path: Path) -> tuple[dict, list[tuple[str, dict]]]:
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise InputError(f"{path}: not valid TOML ({err})") from err
    for key in doc:
        if key not in ("format_version", "defaults", "jobs"):
            raise InputError(f"{path}: unknown top-level key {key!r}"
                             f"{_did_you_mean(key, ['format-version', 'defaults', 'jobs'])}")
    version = doc.get("format_version", MANIFEST_VERSION)
    if version != MANIFEST_VERSION:
        raise InputError(f"{path}: format_version: expected {MANIFEST_VERSION}, got {version!r}")
    defaults = doc.get("defaults", {})
    if not isinstance(defaults, dict):
        raise InputError(f"{path}: defaults: expected a table ([defaults])")
    jobs = doc.get("jobs", [])
    if not isinstance(jobs, list) or not all(isinstance(j, dict) for j in jobs):
        raise InputError(f"{path}: jobs: expected an array of tables ([[jobs]])")
    return defaults, [(f"[[jobs]] #{i + 1}", job) for i, job in enumerate(jobs)]


def _read_csv(text: str, path: Path) -> tuple[dict, list[tuple[str, dict]]]:
    reader = csv.reader(io.StringIO(text))
    lines = [(reader.line_num, row) for row in reader]
    lines = [(n, row) for n, row in lines if any(c.strip() for c in row) and not row[0].lstrip().startswith("#")]
    if not lines:
        raise InputError(f"{path}: empty manifest (expected a header row: name,command,inputs,...)")
    header = [h.strip() for h in lines[0][1]]
    for i, h in enumerate(header):
        if not h:
            raise InputError(f"{path}: line {lines[0][0]}, column {i + 1}: empty column name in the header")
        if h in header[:i]:
            raise InputError(f"{path}: line {lines[0][0]}: column {h!r} appears twice in the header")
    defaults: dict = {}
    rows = []
    for n, cells in lines[1:]:
        if len(cells) > len(header):
            raise InputError(f"{path}: line {n}: {len(cells)} cells but the header has {len(header)} columns")
        row = {h: c.strip() for h, c in zip(header, cells) if c.strip()}
        if row.get("name") == "*":
            if rows or defaults:
                raise InputError(f"{path}: line {n}: the defaults row (name '*') must be the first row after the "
                                 "header")
            defaults = {k: v for k, v in row.items() if k != "name"}
            continue
        rows.append((f"line {n}", row))
    return defaults, rows


def _command_parsers() -> dict[str, argparse.ArgumentParser]:
    """The parsers of the batch commands this jaxhand has (``fit-landmarks`` may be absent)."""
    from ..cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {c: sub.choices[c] for c in COMMANDS if c in sub.choices}


def _option_keys(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    """The manifest keys of a command: long options without ``--`` and positionals by name."""
    keys = {}
    for action in parser._actions:
        longs = [s for s in action.option_strings if s.startswith("--")]
        if action.option_strings and longs:
            keys[longs[0][2:]] = action
        elif not action.option_strings:
            keys[_norm(action.dest)] = action
    for key in _RESERVED:
        keys.pop(key, None)
    return keys


def _values(value, where: str) -> list[str]:
    """One or several values as strings (a TOML list, or ``;``-separated in a CSV cell)."""
    if isinstance(value, list):
        items = value
    elif isinstance(value, str):
        items = [v.strip() for v in value.split(";")] if ";" in value else [value]
    else:
        items = [value]
    out = []
    for v in items:
        if isinstance(v, bool) or not isinstance(v, str | int | float):
            raise InputError(f"{where}: expected a string or a number, got {v!r}")
        out.append(str(v))
    return out


def _flag(value, where: str) -> bool:
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.strip().lower() in _TRUE + _FALSE:
        return value.strip().lower() in _TRUE
    raise InputError(f"{where}: expected true or false, got {value!r}")


def _job(path: Path, where: str, defaults: dict, row: dict, parsers) -> tuple[Job, set[str]]:
    at = f"{path}: {where}"
    name = row.get("name")
    if name is None or not str(name).strip():
        raise InputError(f"{at}, column 'name': missing (every job needs a name, its output folder)")
    name = str(name).strip()
    if not _NAME.match(name) or name in _RESERVED_NAMES:
        raise InputError(f"{at}, column 'name': {name!r} cannot name a folder (letters, digits, '.', '_', '-'; "
                         "not starting with '.' or '-')")
    at = f"{path}: {where} (job {name!r})"
    command = str(row.get("command", defaults.get("command", "track"))).strip()
    if command not in COMMANDS:
        raise InputError(f"{at}, column 'command': expected one of {', '.join(COMMANDS)}, got {command!r}"
                         f"{_did_you_mean(command, COMMANDS)}")
    if command not in parsers:
        raise InputError(f"{at}, column 'command': {command!r} is not available in this jaxhand "
                         f"(available: {', '.join(parsers)})")
    parser = parsers[command]
    keys = _option_keys(parser)
    positionals = [k for k, a in keys.items() if not a.option_strings]
    for key in row:
        k = _norm(key)
        if k in _RESERVED:
            raise InputError(f"{at}, column {key!r}: {_RESERVED[k]}")
        if k not in keys and k not in _FIELDS and not (k == "inputs" and len(positionals) == 1):
            raise InputError(f"{at}, column {key!r}: not an option of 'jaxhand {command}'"
                             f"{_did_you_mean(key, [*keys, *_FIELDS])}")
    merged, used = {}, set()
    for key, value in defaults.items():
        k = _norm(key)
        if k in _RESERVED:
            raise InputError(f"{path}: defaults, column {key!r}: {_RESERVED[k]}")
        if k in keys or (k == "inputs" and len(positionals) == 1):
            merged[k] = (value, f"{path}: defaults, column {key!r}")
            used.add(k)
    for key, value in row.items():
        if _norm(key) not in _FIELDS:
            merged[_norm(key)] = (value, f"{at}, column {key!r}")
    if "inputs" in merged and len(positionals) == 1 and positionals[0] != "inputs":
        merged.setdefault(positionals[0], merged.pop("inputs"))
    args = [command]
    for k in positionals:
        if k not in merged:
            raise InputError(f"{at}: missing column {k!r} (the command's {k.upper()} argument)")
        value, w = merged[k]
        vals = _values(value, w)
        if keys[k].nargs is None and len(vals) != 1:
            raise InputError(f"{w}: expected one value, got {len(vals)}")
        args += vals
    for k, (value, w) in merged.items():
        action = keys.get(k)
        if action is None or not action.option_strings:
            continue
        flag = f"--{k}"
        if action.nargs == 0:                      # store_true and the like
            if _flag(value, w):
                args.append(flag)
        elif isinstance(action, argparse._AppendAction):
            for v in _values(value, w):
                args += [flag, v]
        elif action.nargs in ("+", "*"):
            args += [flag, *_values(value, w)]
        else:
            vals = _values(value, w)
            if len(vals) != 1:
                raise InputError(f"{w}: expected one value, got {len(vals)}")
            args += [flag, vals[0]]
    _check_parses(parser, args[1:], at)
    return Job(name=name, command=command, args=tuple(args), where=where), used


def _check_parses(parser: argparse.ArgumentParser, args: list[str], at: str) -> None:
    """Parse the job's arguments with the command's own parser (types, choices, required options);
    its error becomes an :class:`InputError` naming the row."""

    def error(message):
        raise InputError(f"{at}: {message}")

    parser.error = error    # this parser instance is built for the check and thrown away
    with contextlib.redirect_stderr(io.StringIO()):
        parser.parse_args([*args, "--out", "-"])
