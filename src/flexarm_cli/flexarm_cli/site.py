"""``flexarm bag``, ``calibrate``, ``keygen`` and ``site``: the files of a site (bags,
calibrations, the link key, the site folder)."""
from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

from flexarm_cli.common import (
    Outcome,
    check_bag_path,
    client_session,
    deg,
    mm,
    progress_printer,
)
from flexarm_recording.results.outcome_text import (
    Exit,
)


def cmd_bag(args: argparse.Namespace) -> dict[str, Any]:
    """Inspect a recorded bag (info) or export its trials and figures as CSV + PNG (export)."""
    check_bag_path(args.path)
    from mcap.exceptions import McapError

    from flexarm_recording.bag_tools import (
        bag_info,
        export_figures,
        export_trials,
        format_bag_info,
    )

    say = progress_printer(args)
    try:
        if args.action == 'info':
            info = bag_info(args.path, say)
            print(format_bag_info(info))
            return {'ok': True, **info}
        out_dir = args.out or str(args.path).rstrip('/')
        csv_path, png_path = export_trials(args.path, out_dir, args.namespace, say)
        files = export_figures(args.path, out_dir, args.namespace, say)
    except McapError as exc:
        raise Outcome(f'{args.path} is damaged: {exc}', Exit.FAILED) from None
    print(f'trials: {csv_path}\nplot:   {png_path}' + ''.join(f'\nfile:   {p}' for p in files))
    return {'ok': True, 'csv': str(csv_path), 'png': str(png_path),
            'files': [str(p) for p in files]}


def cmd_calibrate(args: argparse.Namespace) -> dict[str, Any]:
    """Measure the camera's error in the tool frame against a reference; correct for it. With
    --camera, first the camera's own parameters that the plate shows."""
    from flexarm_cli.calibration import calibrate_lens, calibrate_tool
    from flexarm_core.paths import CALIBRATION_DIR

    folder = CALIBRATION_DIR / args.namespace
    path = Path(args.file) if args.file else folder / 'tool_camera.json'
    say = progress_printer(args)
    out: dict[str, Any] = {'ok': True}
    with client_session(args, learner=False) as client:
        if args.camera:
            camera_path = Path(args.camera_file) if args.camera_file else folder / 'camera.json'
            change, lens, lens_details = calibrate_lens(client, camera_path, args.timeout, say)
            print(f'camera: {change.describe()} (from {lens.views} images, '
                  f'{lens.holes} holes; reprojection {lens.rms_before_px:.3f} px -> '
                  f'{lens.rms_after_px:.3f} px); stored in {camera_path}, the vision node '
                  f'measures through it from now on; as a camera driver\'s camera_info YAML in '
                  f'{lens_details["camera_info_file"]}.\n  determined: {lens.determined}\n  '
                  f'not determined from the plate: {lens.not_determined}', flush=True)
            out.update(camera_correction=change.as_list(), camera_path=str(camera_path),
                       camera_info_file=lens_details['camera_info_file'], camera=lens_details)
        c, found, details = calibrate_tool(client, args.reference_topic, path, args.timeout,
                                           say)
    print(f'camera error in the tool frame: axial {mm(c.axial):.4f} mm, lateral '
          f'{mm(c.lateral):.4f} mm, angle {deg(c.angle):.5f} deg ({found.poses} poses; largest '
          f'deviation of one pose {mm(found.spread[0]):.4f} mm, {deg(found.spread[1]):.5f} '
          f'deg); stored in {path}, the vision node corrects for it from now on')
    return {**out, 'tool_correction': c.as_list(), 'path': str(path), **details}


def cmd_keygen(args: argparse.Namespace) -> dict[str, Any]:
    """Write a new site key for the controller link (give it to the PC and the controller)."""
    from flexarm_bridge.link_auth import make_key

    if os.path.exists(args.path):
        raise ValueError(f'{args.path} exists; a new key would lock out whoever uses it')
    path = make_key(args.path)
    print(f'site key written to {path} (mode 600). Use it on both ends: '
          f'flexarm up --robot bridge --link-key {path}, and the controller\'s configuration')
    return {'ok': True, 'path': str(path)}


def cmd_site(args: argparse.Namespace) -> dict[str, Any]:
    """Write a site folder's starting point (init): the site's own params files over the
    clone's, for a real arm behind the bridge or ros2_control (then: flexarm up --site DIR)."""
    from flexarm_cli.site_folder import write_site

    folder = Path(args.dir).expanduser().resolve()
    written = write_site(folder, args.robot)
    print('\n'.join(f'wrote {path}' for path in written)
          + f'\nnext: edit them, then flexarm up --site {folder} --robot {args.robot}')
    return {'ok': True, 'site': str(folder), 'files': [str(path) for path in written]}
