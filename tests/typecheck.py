"""The runtime type checker pytest applies to jaxhand (``--jaxtyping-packages`` in pyproject):
beartype with PEP 484's numeric tower, so an ``int`` passes where a ``float`` is annotated."""

from beartype import BeartypeConf, beartype

checker = beartype(conf=BeartypeConf(is_pep484_tower=True))
