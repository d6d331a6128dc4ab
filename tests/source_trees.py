"""The syntax trees of the project's source files, parsed once per test process.

The house's static scans (tests/house/test_layers.py, test_packaging.py, test_command_rooms.py and
tests/inputs/test_fields.py) each walk the tree of every file of ``src/``: one parse of the tree is
~0.8 s of CPU, paid once here instead of once per scan. A file is read each time (a scan of a copy
or of a changed file sees its text); its text is parsed once, whatever its path. The trees are
shared: a scan reads them and never changes them. They stay in memory for the process (~60 MB for
``src/`` and ``launch_scripts/``).
"""

from __future__ import annotations

import ast

_TREES: dict = {}  # source text -> its module tree


def tree_of_text(text, filename="<unknown>"):
    """The :class:`ast.Module` of ``text`` (a text that does not parse raises, naming ``filename``)."""
    tree = _TREES.get(text)
    if tree is None:
        tree = _TREES[text] = ast.parse(text, filename=filename)
    return tree


def tree(path):
    """The :class:`ast.Module` of the file ``path`` as it reads now (UTF-8)."""
    return tree_of_text(path.read_text(encoding="utf-8"), str(path))
