"""``flexarm accuracy``: how well flexarm would compensate your arm, offline (no graph)."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def cmd_accuracy(args: argparse.Namespace) -> dict[str, Any]:
    """How well flexarm would compensate an arm: its URDF and a CSV of measured poses in,
    held-out errors, bound coverage and a learning curve out (offline, no graph needed;
    docs/accuracy.md)."""
    from flexarm_learning.accuracy_study import study
    from flexarm_learning.measurements import read_csv
    from flexarm_learning.urdf_arm import UrdfArm
    from flexarm_recording.results.accuracy_report import table_text, write_figures

    arm = UrdfArm.from_file(args.urdf, args.tip)
    data = read_csv(args.measurements, arm)
    report = study(arm, data, args.train, splits=args.splits, seed=args.seed,
                   kinds=args.kinds, curve=args.curve)
    if not args.json:
        print(table_text(report))
    figures = write_figures(report, Path(args.plot)) if args.plot else []
    if figures and not args.json:
        print('written: ' + ', '.join(str(p) for p in figures))
    return {'ok': True, **report, 'figures': [str(p) for p in figures]}
