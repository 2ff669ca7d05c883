"""Errors raised by jaxhand at its boundaries (files, CLI arguments, user arrays), and the number check they share."""

import math

__all__ = ["JaxhandError", "ModelFileError", "InputError", "CameraError", "OutputExistsError", "JaxhandWarning",
           "finite_number"]


class JaxhandError(Exception):
    """Base class of every error jaxhand raises on purpose."""


class ModelFileError(JaxhandError, ValueError):
    """A model file or model dictionary is malformed; the message names file, frame and field."""


class CameraError(JaxhandError, ValueError):
    """A camera description is malformed."""


class InputError(JaxhandError, ValueError):
    """A user-supplied array, pose or argument has the wrong shape, dtype or value."""


class OutputExistsError(InputError):
    """An output folder already holds a run; the caller decides whether to overwrite or resume it."""


class JaxhandWarning(UserWarning):
    """Input that is accepted but probably not what was meant (the CLI prints it as one line)."""


def finite_number(value) -> bool:
    """Whether ``value`` is a finite int or float (not a bool): the check of a number read from a
    settings or data file."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
