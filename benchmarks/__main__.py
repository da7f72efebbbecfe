# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""``python -m benchmarks <case> [arguments]``: run one benchmark (``--list``: the cases, ``<case> -h``: its arguments)."""

from __future__ import annotations

import importlib
import pkgutil
import sys

from . import ALIASES, HELPERS


def cases() -> list[str]:
    """The benchmark modules of this package."""
    package = importlib.import_module(__package__)
    return sorted(
        m.name for m in pkgutil.iter_modules(package.__path__) if not m.name.startswith("_") and m.name not in HELPERS
    )


def describe() -> str:
    lines = [
        "usage: python -m benchmarks <case> [arguments]   (python -m benchmarks <case> -h: its arguments)",
        "",
        "cases:",
    ]
    package = importlib.import_module(__package__)
    for name in cases():
        spec = importlib.util.find_spec(f"{package.__name__}.{name}")
        doc = ""
        with open(spec.origin) as f:
            text = f.read()
        start = text.find('"""')
        if start >= 0:
            doc = text[start + 3 :].split("\n", 1)[0].strip().rstrip(".")
        alias = [a for a, m in ALIASES.items() if m == name]
        label = f"{name} ({', '.join(alias)})" if alias else name
        lines.append(f"  {label:32s} {doc}")
    return "\n".join(lines)


def main(argv: list[str] | None = None):
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv or argv[0] in ("-h", "--help", "--list"):
        print(describe())
        return None
    name = ALIASES.get(argv[0], argv[0])
    if name not in cases():
        print(f"unknown case {argv[0]!r}\n\n{describe()}", file=sys.stderr)
        raise SystemExit(2)
    module = importlib.import_module(f"{__package__}.{name}")
    sys.argv[0] = f"python -m benchmarks {name}"
    return module.main(argv[1:])


if __name__ == "__main__":
    main()
