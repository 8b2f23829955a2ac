"""Pictures of a plan: an interactive HTML animation, a storyboard and the paper's Fig. 3.

Everything is built from a plan file alone (see the file formats) and the URDF and meshes it names.
The optional extra ``viz`` (``pip install 'openup-ompl[viz]'``) brings what draws them:
meshcat (its three.js viewer, inlined in the HTML) and matplotlib. They are imported only
when a picture is made; a missing one raises :class:`~openup_ompl.exceptions.MissingExtra`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from openup_ompl._io import check_dir
from openup_ompl.exceptions import ConfigError
from openup_ompl.viz._mpl import _pyplot
from openup_ompl.viz._scene import PlanScene
from openup_ompl.viz.html import HtmlOptions, _meshcat, write_html
from openup_ompl.viz.law import plot_hand_law
from openup_ompl.viz.storyboard import StoryboardOptions, write_storyboard


@dataclass(frozen=True)
class Shown:
    """The files :func:`show` wrote.

    Attributes:
        html: The interactive animation (one self-contained HTML file).
        storyboard: The storyboard PNG.
        hand_law: The paper's Fig. 3 for the plan (PNG).
    """

    html: Path
    storyboard: Path
    hand_law: Path


def show(
    plan: str | Path,
    out_dir: str | Path | None = None,
    html: HtmlOptions | None = None,
    storyboard: StoryboardOptions | None = None,
) -> Shown:
    """Write the pictures of a plan file: ``<stem>.html``, ``<stem>_storyboard.png`` and
    ``<stem>_hand_law.png`` in ``out_dir`` (default: the plan file's directory).

    Args:
        plan: The plan file.
        out_dir: Where to write (default: the plan file's directory).
        html: Animation options (default :class:`HtmlOptions`).
        storyboard: Storyboard options (default :class:`StoryboardOptions`).

    Returns:
        The three paths written (:class:`Shown`).

    Raises:
        ConfigError: ``plan`` is not a path (draw a :class:`~openup_ompl.Plan` in memory
            with :meth:`PlanScene.from_plan` and the writers), the file is not a readable
            plan, its URDF or meshes cannot be loaded, ``out_dir`` is a file, or the
            options are of another type.
        MissingExtra: matplotlib or meshcat is not installed.
    """
    if not isinstance(plan, (str, os.PathLike)):
        raise ConfigError("plan", type(plan).__name__, "a plan file's path")
    if html is not None and not isinstance(html, HtmlOptions):
        raise ConfigError("html", html, "HtmlOptions or None")
    if storyboard is not None and not isinstance(storyboard, StoryboardOptions):
        raise ConfigError("storyboard", storyboard, "StoryboardOptions or None")
    # A missing extra is reported before anything is written.
    _pyplot()
    _meshcat()
    plan = Path(plan)
    scene = PlanScene.from_file(plan)
    out = check_dir(Path(out_dir) if out_dir is not None else plan.parent)
    stem = plan.stem
    # The storyboard loads the robot's meshes first: a missing one fails with no file written.
    board = write_storyboard(scene, out / f"{stem}_storyboard.png", storyboard)
    page = write_html(scene, out / f"{stem}.html", html)
    figure = plot_hand_law(scene, out / f"{stem}_hand_law.png")
    return Shown(html=page, storyboard=board, hand_law=figure)


__all__ = [
    "HtmlOptions",
    "PlanScene",
    "Shown",
    "StoryboardOptions",
    "show",
    "write_html",
    "write_storyboard",
]
