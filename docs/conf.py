# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Sphinx configuration of the newton-fluid documentation (build with -W: warnings are errors)."""

project = "newton-fluid"
author = "The newton-fluid Developers"
copyright = "2026, The newton-fluid Developers"
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax"]
exclude_patterns = ["_build", "*.md"]
autodoc_typehints = "none"
napoleon_google_docstring = True
html_theme = "alabaster"
