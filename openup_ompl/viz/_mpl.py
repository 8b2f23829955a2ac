"""The one gateway to matplotlib: every figure of the package draws through it.

matplotlib is an optional extra (``pip install 'openup-ompl[viz]'``); it is imported only
when a figure is made, on the Agg backend (no display), and a missing one raises
:class:`~openup_ompl.exceptions.MissingExtra`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from openup_ompl._io import make_dir
from openup_ompl.exceptions import MissingExtra


def _pyplot() -> Any:
    """matplotlib's pyplot on the Agg backend (no display), or :class:`MissingExtra`."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise MissingExtra("matplotlib", "viz") from None
    return plt


def _save(fig: Any, out: str | Path, dpi: int) -> Path:
    """Write ``fig`` to the PNG ``out`` (creating its directory) and close it, written or
    not."""
    out = Path(out)
    try:
        make_dir(out.parent)
        fig.savefig(out, dpi=dpi)
    finally:
        _pyplot().close(fig)
    return out
