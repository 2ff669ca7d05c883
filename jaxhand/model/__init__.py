"""Kinematic models: modified-DH trees, built-in hands, model files, MJCF/URDF import, mirroring."""

from .._errors import ModelFileError
from ._file import FORMAT_VERSION as FORMAT_VERSION
from ._file import load_model as load_model
from ._file import model_from_dict as model_from_dict
from ._file import model_to_dict as model_to_dict
from ._file import save_model as save_model
from ._mirror import mirror_model as mirror_model
from ._mirror import mirror_q as mirror_q
from ._mjcf import load_mjcf as load_mjcf
from ._model import Model as Model
from ._palm import add_palm as add_palm
from ._tree import occluders_as_links as occluders_as_links
from ._urdf import load_urdf as load_urdf
from .builtin import builtin_model as builtin_model
from .builtin import builtin_names as builtin_names
from .builtin import builtin_spec as builtin_spec

__all__ = ["Model", "builtin_model", "builtin_names", "builtin_spec", "load_model", "save_model",
           "model_from_dict", "model_to_dict", "FORMAT_VERSION", "get_model", "load_mjcf", "load_urdf",
           "mirror_model", "mirror_q", "occluders_as_links", "add_palm"]


def get_model(name_or_path) -> Model:
    """A built-in model by name, or a model file by path (``.toml``/``.json``, MJCF ``.xml``, ``.urdf``)."""
    from pathlib import Path

    if isinstance(name_or_path, Model):
        return name_or_path
    if str(name_or_path) in builtin_names():
        return builtin_model(str(name_or_path))
    p = Path(name_or_path)
    if p.suffix in (".toml", ".json", ".xml", ".urdf"):
        return load_model(p)
    if p.suffix or p.exists():
        raise ModelFileError(f"{p}: not a model file jaxhand reads (model files are .toml, .json, MJCF .xml or "
                             f".urdf) nor a built-in model ({', '.join(builtin_names())})")
    return builtin_model(str(name_or_path))  # raises the "unknown model" error listing built-ins
