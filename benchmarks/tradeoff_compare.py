# SPDX-License-Identifier: GPL-3.0-or-later
"""Auto before and after, per scene, from two tradeoff_suite.py runs (not a test).

    .venv/bin/python benchmarks/tradeoff_compare.py BEFORE.json AFTER.json [--append AFTER.md]

Per scene of AFTER: Auto's relative RMSE, frame time and error against the measured front at its
time (tradeoff_suite.verdicts: on the front within 10 %, in error or in time) in BEFORE's run and in AFTER's, and the
settings Auto had in BEFORE (every pass whose cell exists: the last combination rendered, at Auto's
N) measured in AFTER's own run, so that both sides of the comparison share one machine load. Prints
the markdown section (and appends it to ``--append``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from tradeoff_suite import verdicts  # noqa: E402

PASSES = (("visibility", "visibility"), ("mrp_asg", "MRP-ASG"), ("vpl_pass", "VPLs"))


def _passes(row: dict) -> str:
    ran = [label for key, label in PASSES if row.get("passes", {}).get(key)]
    return ", ".join(ran) or "VSGLs only"


def _verdict(manual: list, row: dict) -> tuple[float, bool]:
    """(error / the front's at the row's time, the suite's Auto target met: tradeoff_suite.verdicts)."""
    auto = verdicts({"manual": manual, "auto": row, "budget": []})["auto"]
    return (math.nan if auto["error_ratio"] is None else auto["error_ratio"]), auto["met"]


def section(before: dict, after: dict, command: str) -> str:
    old = {scene["scene"]: scene for scene in before["scenes"]}
    lines = ["## Auto before and after", "",
             f"`{command}`. Before: main's run (`tradeoff_suite.json`, Auto = the saved settings in Manual mode: "
             "every pass whose cell exists). After: this run, Auto quality mode. \"Old Auto here\": the settings "
             "Auto had before (the last technique combination rendered, at Auto's N) in this run, against this "
             "run's front. Front ratio: Auto's error / the lowest manual error measured at most Auto's time.", "",
             "| scene | before: passes | before: rel RMSE, ms | before: × front | old Auto here: rel RMSE, ms, × front "
             "| after: passes | after: rel RMSE, ms | after: × front | error after / old Auto here |",
             "|---|---|---|---|---|---|---|---|---|"]
    for scene in after["scenes"]:
        name = scene["scene"]
        auto = scene["auto"]
        manual = scene["manual"]
        ratio, met = _verdict(manual, auto)
        same = [row for row in manual if row["vsgl_count"] == auto["vsgl_count"]]
        here = same[-1] if same else None
        here_text = "—"
        if here is not None:
            here_ratio, here_met = _verdict(manual, here)
            here_text = (f"{here['rel']:.3f}, {here['seconds'] * 1e3:.0f}, {here_ratio:.2f}× "
                         f"({'on' if here_met else 'OFF'})")
        before_text = ("—", "—", "—")
        if name in old:
            b = old[name]["auto"]
            v = old[name].get("verdicts") or verdicts(old[name])
            r = v["auto"]["error_ratio"]
            before_text = (_passes(b), f"{b['rel']:.3f}, {b['seconds'] * 1e3:.0f}",
                           f"{r:.2f}× ({'on' if v['auto']['met'] else 'OFF'})" if r is not None else "—")
        worse = f"{auto['rel'] / here['rel']:.3f}" if here is not None else "—"
        lines.append(f"| {name} | {before_text[0]} | {before_text[1]} | {before_text[2]} | {here_text} | "
                     f"{_passes(auto)} | {auto['rel']:.3f}, {auto['seconds'] * 1e3:.0f} | {ratio:.2f}× "
                     f"({'on' if met else 'OFF'}) | {worse} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--append", type=Path)
    args = parser.parse_args(argv)
    command = " ".join([".venv/bin/python", "benchmarks/tradeoff_compare.py",
                        *(argv if argv is not None else sys.argv[1:])])
    text = section(json.loads(args.before.read_text()), json.loads(args.after.read_text()), command)
    if args.append is not None:
        args.append.write_text(args.append.read_text().rstrip("\n") + "\n\n" + text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
