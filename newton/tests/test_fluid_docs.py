# SPDX-FileCopyrightText: Copyright (c) 2026 The newton-fluid Developers
# SPDX-License-Identifier: Apache-2.0

"""The Sphinx documentation builds with warnings as errors."""

import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

DOCS = Path(__file__).resolve().parents[2] / "docs"


class TestFluidDocs(unittest.TestCase):
    def test_docs_build_without_warnings(self):
        if not (DOCS / "conf.py").is_file():
            self.skipTest("docs/ is part of the source checkout, not of the installed wheel")
        with tempfile.TemporaryDirectory() as out:
            result = subprocess.run(
                [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", str(DOCS), out],
                capture_output=True,
                text=True,
                timeout=600,
                check=False,
            )
            self.assertEqual(result.returncode, 0, result.stdout[-3000:] + result.stderr[-3000:])
            self.assertTrue((Path(out) / "formulation.html").is_file())


if __name__ == "__main__":
    unittest.main(verbosity=2)
