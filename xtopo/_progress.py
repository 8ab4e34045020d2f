"""Progress bars for long work: tqdm on a terminal, a widget in a notebook, nothing elsewhere.

``enabled=None`` (auto) shows one when stderr is a terminal or code runs in a Jupyter kernel, and
never in pipes, logs or tests; ``False`` never (``-q`` on the command line). tqdm is imported on
first use only (startup time).
"""

from __future__ import annotations

import importlib.util
import sys

__all__ = ["progress_bar"]


def _in_notebook() -> bool:
    return "ipykernel" in sys.modules


def progress_bar(iterable, *, desc: str, total: int | None = None, unit: str = "it", enabled: bool | None = None):
    """``iterable`` with a progress bar where one is wanted (see the module docstring), else as it is.

    Parameters
    ----------
    iterable : iterable
        What is worked through.
    desc : str
        What the bar says it does (``"reading files"``).
    total : int, optional
        Its length, where ``len(iterable)`` does not give it.
    unit : str
        One step's name (``"file"``).
    enabled : bool, optional
        None: on a terminal or in a notebook; True/False: always/never.
    """
    if enabled is None:
        enabled = _in_notebook() or bool(getattr(sys.stderr, "isatty", lambda: False)())
    if not enabled or importlib.util.find_spec("tqdm") is None:
        return iterable
    if _in_notebook() and importlib.util.find_spec("ipywidgets") is not None:
        from tqdm.notebook import tqdm
    else:
        from tqdm.std import tqdm
    return tqdm(iterable, desc=desc, total=total, unit=unit, leave=False, file=sys.stderr, dynamic_ncols=True)
