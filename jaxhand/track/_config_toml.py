"""TrackConfig as TOML: the text, and the files ``jaxhand track --config`` reads."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Any

from .._errors import InputError
from ._config import TrackConfig, _merge, config_from_dict, config_to_dict
from ._config_checks import need
from ._presets import PRESETS

__all__ = ["config_to_toml", "save_track_config", "load_track_config"]


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")) if not math.isfinite(v) else repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise InputError(f"cannot write {v!r} to TOML")


def _toml_lines(d: dict, prefix: tuple) -> list[str]:
    # TOML has no null: a None is left out, and reading the file gives the field's default back
    lines = [f"{k} = {_toml_value(v)}" for k, v in d.items() if not isinstance(v, dict) and v is not None]
    for k, v in d.items():
        if isinstance(v, dict):
            lines += ["", f"[{'.'.join(prefix + (k,))}]"] + _toml_lines(v, prefix + (k,))
    return lines


def config_to_toml(config: TrackConfig) -> str:
    """The whole tree as TOML text (every field, format version first)."""
    return "\n".join(_toml_lines(config_to_dict(config), ())) + "\n"


def save_track_config(config: TrackConfig, path: str | Path) -> None:
    """Write ``config`` to a TOML file that :func:`load_track_config` reads back exactly."""
    Path(path).write_text(config_to_toml(config))


def load_track_config(path: str | Path, preset: str | None = None) -> TrackConfig:
    """Read a TOML tracking config (missing keys keep their defaults), with the named
    :data:`~jaxhand.track.PRESETS` entry on top when ``preset`` is given. The two are checked
    together, so a file may lean on the preset (a setting that needs the preset's ``support``).

    Raises:
        InputError: naming the file and the key (unknown keys with a "did you mean" hint).
    """
    path = Path(path)
    try:
        data: dict[str, Any] = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise InputError(f"{path}: {err}") from err
    if preset is not None:
        need(preset in PRESETS, "preset", f"unknown preset {preset!r}; valid: {', '.join(PRESETS)}")
        data = _merge(data, PRESETS[preset])
    try:
        return config_from_dict(data)
    except InputError as err:
        raise InputError(f"{path}: {err}") from None
