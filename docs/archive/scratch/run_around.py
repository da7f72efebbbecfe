# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""Scratch helper: run ``python -m benchmarks ARGS`` (or the script ``ARGS[0]``) with ``SolverXPBD.step`` replaced."""

import runpy
import sys

import newton


def run_around(replacement):
    """Run ``python -m benchmarks ARGS`` (or the script ``ARGS[0]``) with ``SolverXPBD.step`` replaced."""
    newton.solvers.SolverXPBD.step = replacement
    sys.path.insert(0, ".")
    if sys.argv[1].endswith(".py"):
        script = sys.argv[1]
        sys.argv = sys.argv[1:]
        runpy.run_path(script, run_name="__main__")
    else:
        sys.argv = ["benchmarks", *sys.argv[1:]]
        runpy.run_module("benchmarks", run_name="__main__")
