# SPDX-License-Identifier: GPL-3.0-or-later
"""The speed/accuracy trade of VSGL indirect light on demo.blend, measured against Cycles (not a test).

    .venv/bin/python benchmarks/speed_accuracy.py [--quick] [--regenerate-reference]

The entry script of the ``benchmarks/tradeoff/`` package: what is measured, how and how long it
takes is the package's doc (``benchmarks/tradeoff/__init__.py``); results in ``benchmarks/results/``.
"""

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
# The add-on (vsgl_addon), the tests' Cycles/EEVEE helpers (cycles_truth) and this folder (the
# tradeoff package, gpu_timing), as the package imports them.
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))
sys.path.insert(0, str(REPO / "benchmarks"))

from tradeoff.cli import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
