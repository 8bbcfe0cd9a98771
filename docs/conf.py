"""Sphinx configuration of the swe_sphere site: MyST pages, the PyData theme, numpydoc for the
docstrings' sections, sphinx-gallery for the worked examples (docs/examples -> docs/gallery).

Built by one command from the repository root (the README's)::

    python -m sphinx -W --keep-going -b html docs docs/_build/html

No intersphinx: the build needs no network beyond the package index the extra came from.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import swe_sphere

# the pages generated from the code when the site is built (_ext/: the scene keys, the steppers,
# the run file's contents)
sys.path.insert(0, str(Path(__file__).parent / "_ext"))

project = "swe_sphere"
author = "swe_sphere contributors"
copyright = "swe_sphere contributors, BSD-3-Clause"
release = version = swe_sphere.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "sphinxarg.ext",
    "sphinx_gallery.gen_gallery",
    "scene_keys",
    "steppers_page",
    "run_file_page",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"

# examples/ holds sphinx-gallery's sources, rendered into gallery/ (not read as pages).
exclude_patterns = ["_build", "_templates", "examples"]


# MyST: $...$ and $$...$$ maths, \begin{align} blocks, ::: fences, definition lists; heading
# anchors down to ####, so that [text](page.md#a-heading) links resolve (and, under -W, fail
# the build when they do not: MyST's myst.xref_missing).
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 4

# API pages: autosummary writes one page a name (reference/api/*.rst at build time, not
# committed); numpydoc renders the Parameters/Returns/Raises sections. A class's methods are
# listed by autosummary's own template, so numpydoc's member tables (which would want a stub
# page for every inherited method) stay off.
autosummary_generate = True
templates_path = ["_templates"]  # autosummary/class.rst: a class with its documented members
autodoc_typehints = "none"  # the numpydoc sections give the types, in the field's words
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False

html_theme = "pydata_sphinx_theme"
html_title = "swe_sphere"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
}

# The worked examples run at build time (each on a tiny grid), on the CPU unless asked.
os.environ.setdefault("SWE_SPHERE_DEVICE", "cpu")
sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "gallery",
    "filename_pattern": r"\.py$",  # every example runs, whatever its name
    "ignore_pattern": r"__init__\.py|^_",  # helpers named _*.py are imported, not shown (matched on the file name)
    # the gallery's sections from a first run to data assimilation, each a folder of docs/examples
    "subsection_order": ["examples/runs", "examples/studies", "examples/gradients", "examples/assimilation"],
    "abort_on_example_error": True,
    "matplotlib_animations": False,
    "download_all_examples": False,
    # no execution-time pages: sphinx-gallery writes them with DataTables, jQuery and Bootstrap
    # from CDNs, which a site read offline cannot load (the pages' maths is Unicode text, so no
    # page loads MathJax from its CDN either)
    "write_computation_times": False,
}
