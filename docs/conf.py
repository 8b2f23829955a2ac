"""Sphinx configuration of the openup-ompl documentation (built with ``-n -W`` in CI)."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # the checkout being documented, not another installed copy

import openup_ompl  # noqa: E402

project = "openup-ompl"
author = "openup-ompl contributors"
copyright = "openup-ompl contributors"
release = openup_ompl.__version__
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "**/*.csv"]
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

html_theme = "furo"
html_title = f"openup-ompl {release}"
html_static_path: list[str] = []

# Google-style docstrings (napoleon), types in the description rather than the signature.
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
napoleon_use_ivar = True  # a dataclass's fields are documented once, by autodoc
autodoc_typehints = "description"
autodoc_typehints_description_target = "documented_params"
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "undoc-members": True, "show-inheritance": True}
# A name used by two modules (``object``, a re-exported exception) links to one of them.
suppress_warnings = ["ref.python"]

# The build runs offline (no intersphinx inventories): references to the standard library
# and to the external libraries' types are not resolved, the rest must be.
EXTERNAL = (
    "numpy",
    "np",
    "npt",
    "ompl",
    "ob",
    "og",
    "ot",
    "pinocchio",
    "pin",
    "coal",
    "hppfcl",
    "mujoco",
    "scipy",
    "matplotlib",
    "meshcat",
    "dask",
    "distributed",
    "argparse",
    "pathlib",
    "collections",
    "typing",
    "typing_extensions",
    "os",
    "io",
    "concurrent",
    "subprocess",
    "dataclasses",
    "enum",
    "json",
    "types",
    "abc",
    "contextlib",
    "random",
    "threading",
    "multiprocessing",
    "tomllib",
    "tomli",
    "xml",
    "ET",
    "Path",
    "NDArray",
    "ArrayLike",
    "FloatArray",
)
nitpick_ignore_regex = [
    # private names are not documented; a TypeVar is not a class
    (r"py:.*", r"(.*\.)?_[A-Za-z]\w*(\.\w+)*"),
    (r"py:class", r"openup_ompl\..*\.[A-Z]"),
    (r"py:.*", rf"({'|'.join(EXTERNAL)})(\..*)?"),
    # builtins and typing names as they appear in annotations
    (
        r"py:.*",
        r"(Any|Callable|Iterable|Iterator|Sequence|Mapping|MutableMapping|Literal|"
        r"Self|TypeAlias|Optional|Union|ClassVar|Final|Generator|TextIO|IO|"
        r"NoneType|ellipsis|Ellipsis|array-like|optional|\.\.\.)",
    ),
    (
        r"py:.*",
        r"(int|float|str|bool|bytes|dict|list|tuple|set|frozenset|object|type|"
        r"complex|slice|range|Exception|ValueError|TypeError|KeyError|OSError|"
        r"RuntimeError|FileNotFoundError|KeyboardInterrupt)",
    ),
]


def _public_modules() -> list[str]:
    """Every public module of the package (no leading underscore anywhere in its name,
    no ``__main__``), found by walking the package: the API page follows the code."""
    names = []
    for info in pkgutil.walk_packages(openup_ompl.__path__, "openup_ompl."):
        parts = info.name.split(".")
        if any(part.startswith("_") for part in parts):
            continue
        names.append(info.name)
    return sorted(names)


def _reexported(package: str) -> list[str]:
    """Autodoc directives for the names a package exports from its private modules
    (``openup_ompl.viz.PlanScene`` lives in ``viz/_scene.py``): documented where users
    import them from."""
    module = importlib.import_module(package)
    lines = []
    for name in getattr(module, "__all__", ()):
        obj = getattr(module, name)
        home = getattr(obj, "__module__", "") or ""
        if not any(part.startswith("_") for part in home.split(".")) or name.startswith("_"):
            continue
        if isinstance(obj, type):
            kind = "autoclass"
        else:
            kind = "autofunction" if callable(obj) else "autodata"
        lines.append(f".. {kind}:: {package}.{name}")
    return lines


def _api_reference() -> str:
    """The API page's body: one section and ``automodule`` per public module. A package's
    re-exports are documented where they are defined, so a package gets no members."""
    blocks = []
    for name in _public_modules():
        is_package = hasattr(importlib.import_module(name), "__path__")
        options = ":no-members:" if is_package else ":members:"
        rst = [f".. automodule:: {name}", f"   {options}", ""]
        if is_package:
            rst += _reexported(name)
        body = "\n".join(rst)
        blocks.append(f"## `{name}`\n\n```{{eval-rst}}\n{body}\n```\n")
    return "\n".join(blocks)


def _cli_parser():  # noqa: ANN202
    """The command line's argparse parser, wherever the CLI module defines it."""
    for name in ("openup_ompl.cli", "openup_ompl.__main__"):
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        if hasattr(module, "build_parser"):
            return module.build_parser()
    raise ImportError("no build_parser in openup_ompl.cli or openup_ompl.__main__")


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _cli_options(command: str) -> str:
    """A command's usage line and options table, from the parser itself (so a page never
    lists an option the command lacks)."""
    import argparse

    parser = _cli_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    command_parser = sub.choices[command]
    usage = " ".join(command_parser.format_usage().split())
    rows = ["| argument | meaning |", "|---|---|"]
    for action in command_parser._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        name = ", ".join(action.option_strings) or action.dest
        if action.option_strings and action.nargs != 0:
            name += f" {action.metavar or action.dest.upper()}"
            if action.nargs in ("+", "*"):
                name += " ..."
        meaning = (action.help or "").replace("%(default)s", str(action.default))
        rows.append(f"| `{_cell(name)}` | {_cell(meaning)} |")
    return "```text\n" + usage.removeprefix("usage: ") + "\n```\n\n" + "\n".join(rows) + "\n"


def _fill_api(app, docname: str, source: list[str]) -> None:  # noqa: ANN001
    if docname == "api/index":
        source[0] = source[0].replace("<!-- API-MODULES -->", _api_reference())
    for command in re.findall(r"<!-- CLI-OPTIONS ([\w-]+) -->", source[0]):
        source[0] = source[0].replace(f"<!-- CLI-OPTIONS {command} -->", _cli_options(command))


def _lookup(dotted: str) -> bool:
    """Whether ``dotted`` names an existing Python object (module, then attributes)."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        try:
            for name in parts[cut:]:
                obj = getattr(obj, name)
        except AttributeError:
            return False
        return True
    return False


def _resolve_by_name(app, env, node, contnode):  # noqa: ANN001, ANN201
    """Resolve a Python reference by a path other than its definition's.

    A reference to a documented object (``openup_ompl.Plan``, ``ConfigError`` from another
    module, ``PlanScene.from_file``) links to the one documented object whose dotted name
    ends the same. A reference to an existing but undocumented name (a module constant or
    helper outside its module's ``__all__``) is rendered as code without a link. Anything
    else (a stale or misspelt name) stays a warning, so ``-n`` still catches it.
    """
    if node.get("refdomain") != "py":
        return None
    target = re.sub(r"\s+", "", node["reftarget"]).lstrip("~.")
    tail = target.split(".")
    domain = env.get_domain("py")
    for width in (2, 1):
        if len(tail) < width:
            continue
        suffix = "." + ".".join(tail[-width:])
        found = [name for name in domain.objects if name.endswith(suffix)]
        if len(found) == 1:
            resolved = domain.resolve_any_xref(
                env, node["refdoc"], app.builder, found[0], node, contnode
            )
            if resolved:
                return resolved[0][1]
    module, cls = node.get("py:module") or "", node.get("py:class") or ""
    scopes = [target, f"{module}.{target}", f"{module}.{cls}.{target}"]
    if any(_lookup(name) for name in scopes if not name.startswith(".")):
        return contnode
    if node["reftype"] == "attr" and _instance_attribute(module, cls, target):
        return contnode
    return None


def _instance_attribute(module: str, cls: str, target: str) -> bool:
    """Whether ``target`` (``name`` or ``Class.name``) is an attribute that the class's
    own code, or a base class's, assigns on ``self`` (set in ``__init__``, so not visible
    on the class; a tuple assignment ``self.a, self.b = ...`` counts)."""
    *owner, name = target.split(".")
    path = ".".join([module, *(owner or [cls])])
    parts = path.split(".")
    try:
        klass = getattr(importlib.import_module(".".join(parts[:-1])), parts[-1])
        sources = [inspect.getsource(base) for base in inspect.getmro(klass)[:-1]]
    except (ImportError, AttributeError, TypeError, OSError, ValueError):
        return False
    assigned = re.compile(rf"self\.{re.escape(name)}\b[^=\n]*=(?!=)")
    return any(assigned.search(source) for source in sources)


def _prose_attribute_docstrings() -> None:
    """This project's constants document themselves in prose (``Largest pose error (m)
    accepted: ...``); napoleon would read the text before the first colon as a type."""
    from sphinx.ext.napoleon.docstring import GoogleDocstring

    GoogleDocstring._parse_attribute_docstring = lambda self: self._consume_to_end()


def setup(app):  # noqa: ANN001, ANN201
    _prose_attribute_docstrings()
    app.connect("source-read", _fill_api)
    app.connect("missing-reference", _resolve_by_name)
