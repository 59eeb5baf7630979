"""``tire-estimation convert comma2k19|revs250lm|husky ...``: measured data to contract bags."""

from __future__ import annotations

import argparse
import shlex
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any


def _command(args: argparse.Namespace, dataset: str, source: Path) -> str:
    parts = ["tire-estimation", "convert", dataset, str(source), "--out", str(args.out)]
    if args.overwrite:
        parts.append("--overwrite")
    return shlex.join(parts)


def _convert(
    args: argparse.Namespace, dataset: str, source: Path, convert: Callable[..., Path]
) -> int:
    """Run one converter on ``source`` and print what it wrote, its size and the time."""
    t0 = time.perf_counter()
    command = _command(args, dataset, source)
    path = convert(source, args.out, overwrite=args.overwrite, command=command)
    print(f"wrote {path} ({_size_mb(path):.1f} MB in {time.perf_counter() - t0:.1f} s)")
    return 0


def _cmd_comma2k19(args: argparse.Namespace) -> int:
    from tire_estimation.convert.comma2k19 import convert_comma2k19

    return _convert(args, "comma2k19", args.segment_dir, convert_comma2k19)


def _cmd_revs250lm(args: argparse.Namespace) -> int:
    from tire_estimation.convert.revs250lm import convert_revs250lm

    return _convert(args, "revs250lm", args.data_dir, convert_revs250lm)


def _cmd_husky(args: argparse.Namespace) -> int:
    from tire_estimation.convert.husky import convert_husky

    return _convert(args, "husky", args.data_dir, convert_husky)


def _size_mb(path: Path) -> float:
    return sum(p.stat().st_size for p in Path(path).rglob("*") if p.is_file()) / 1e6


def add_convert_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``convert`` (``comma2k19``, ``revs250lm``, ``husky``) to the main CLI's sub-parsers."""
    conv = subparsers.add_parser("convert", help="convert measured data to a contract bag")
    sub = conv.add_subparsers(dest="dataset", required=True, metavar="DATASET")

    comma = sub.add_parser(
        "comma2k19",
        help="a comma2k19 segment folder (CAN, IMU, u-blox GNSS, global_pose reference)",
    )
    comma.add_argument("segment_dir", type=Path, metavar="SEGMENT_DIR")
    comma.add_argument("--out", required=True, type=Path, help="bag directory to create")
    comma.add_argument("--overwrite", action="store_true", help="replace an existing bag")
    comma.set_defaults(func=_cmd_comma2k19)

    revs = sub.add_parser(
        "revs250lm", help="the Revs Ferrari 250 LM text export (steering, IMU, INS velocities)"
    )
    revs.add_argument("data_dir", type=Path, metavar="DATA_DIR")
    revs.add_argument("--out", required=True, type=Path, help="bag directory to create")
    revs.add_argument("--overwrite", action="store_true", help="replace an existing bag")
    revs.set_defaults(func=_cmd_revs250lm)

    husky = sub.add_parser(
        "husky",
        help="robot_localization's Clearpath Husky test1.bag (ROS 1: drive odometry, IMU, GPS)",
    )
    husky.add_argument(
        "data_dir", type=Path, metavar="DATA_DIR", help="folder with test1.bag (or the bag)"
    )
    husky.add_argument("--out", required=True, type=Path, help="bag directory to create")
    husky.add_argument("--overwrite", action="store_true", help="replace an existing bag")
    husky.set_defaults(func=_cmd_husky)
    return conv
