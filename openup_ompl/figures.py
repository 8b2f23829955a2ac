"""Old home of the hand-law figures, kept so that existing imports keep working.

The figures live in :mod:`openup_ompl.viz.law`, matplotlib behind
:mod:`openup_ompl.viz._mpl`, and :class:`~openup_ompl.exceptions.MissingExtra` in
:mod:`openup_ompl.exceptions`.
"""

from openup_ompl.exceptions import MissingExtra
from openup_ompl.viz._mpl import _pyplot, _save
from openup_ompl.viz.law import plot_hand_law, plot_law

__all__ = ["MissingExtra", "_pyplot", "_save", "plot_hand_law", "plot_law"]
