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


def write_record(benchmark: str, device, result: dict, path: str | None) -> dict:
    """The benchmark's JSON record: its name, :func:`machine_record` and ``result``; written to ``path`` if given.

    Args:
        benchmark: The benchmark's name.
        device: The ``wp.Device`` it ran on.
        result: Its measurements and settings.
        path: Where to write the JSON, or ``None``.
    """
    import json  # noqa: PLC0415

    record = {"benchmark": benchmark, **machine_record(device), **result}
    if path:
        with open(path, "w") as f:
            json.dump(record, f, indent=2)
    return record
