"""Runnable reproductions of the documents' worked examples.

- ``python -m jaxhand.examples.chapter3 [--out DIR]``: the planar R, P, PR and RR chains of
  thesis §3.2, their convergence tables (Tables 3.1-3.6), iteration overlays (Figs. 3.17,
  3.23, 3.27, 3.30) and the RR cost surface with both descent paths (Fig. 3.31).
"""

__all__: list[str] = []
