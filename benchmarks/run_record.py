# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""What every benchmark's JSON records about where it ran: machine, CPU, device, versions and date."""

from __future__ import annotations

import datetime
import platform


def machine_record(device) -> dict:
    """The machine, its CPU, the Warp device (its name, or ``"cpu"``, and alias), Warp, Newton and the date.

    Args:
        device: The ``wp.Device`` the benchmark ran on.
    """
    # (imported here: a benchmark that drives another simulator may need to import Warp after it)
    import warp as wp  # noqa: PLC0415

    import newton  # noqa: PLC0415

    return {
        "machine": platform.node(),
        "cpu": platform.processor() or platform.machine(),
        "device": device.name if device.is_cuda else "cpu",
        "device_alias": device.alias,
        "warp": wp.config.version,
        "newton": newton.__version__,
        "date": datetime.date.today().isoformat(),
    }


#: what every run of the fluid records beside its time (in a sweep, every row)
RUN_FIELDS = ("particles", "substeps", "iterations", "mean_abs_density_error", "max_compression")


def write_record(
    benchmark: str, device, result: dict, path: str | None, rows: list | None = None, fluid_step: bool = True
) -> dict:
    """The benchmark's JSON record: its name, :func:`machine_record`, ``result`` and ``rows``; written to ``path``.

    Every run (``result``, or each of ``rows`` for a sweep, with the settings ``result`` shares with them)
    must carry :data:`RUN_FIELDS`: the particle count, substeps per frame, iterations, and the density
    error (mean ``|rho/rho0 - 1|`` and the largest compression) beside its time; a record that lacks one
    is refused before anything is written.

    Args:
        benchmark: The benchmark's name.
        device: The ``wp.Device`` it ran on.
        result: Its measurements and settings (of the one run, or shared by the rows).
        path: Where to write the JSON, or ``None``.
        rows: The runs of a sweep, each a dict, or ``None`` for one run.
        fluid_step: ``False`` for a benchmark that times no fluid step (then only ``particles`` is required).
    """
    import json  # noqa: PLC0415

    required = RUN_FIELDS if fluid_step else RUN_FIELDS[:1]
    for k, run in enumerate([result] if rows is None else rows):
        # a sweep's shared settings (substeps, say) count for each of its rows
        missing = [f for f in required if f not in run and f not in result]
        if missing:
            where = "" if rows is None else f" row {k}"
            raise ValueError(
                f"benchmark {benchmark!r}: the record{where} lacks {missing}; every run records {required}"
            )
    record = {"benchmark": benchmark, **machine_record(device), **result}
    if rows is not None:
        record["rows"] = rows
    if path:
        with open(path, "w") as f:
            json.dump(record, f, indent=2)
    return record
