# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""newton-fluid's benchmarks: ``python -m benchmarks <case> [arguments]`` (``--list`` names the cases).

Each case is a module of this package with a ``main(argv)`` that prints a short table and writes a
JSON record (:mod:`.run_record`: machine, device, versions, and beside every time the particle
count, substeps, iterations and density error). ``benchmarks/gpu_session.sh`` runs the ones whose
numbers the docs give on a GPU machine.
"""

#: short names of the cases the docs use most
ALIASES = {
    "perf": "dam_break",
    "render": "render_fluid",
    "worlds": "batched_worlds",
    "validate": "validate_dam_break",
    "stability": "stability_map",
    "reference": "reference_dfsph",
    "exact": "accuracy_chart",
    "rest": "rest_column",
}
#: modules that are shared by the cases, not cases themselves
HELPERS = ("frames", "run_record")
