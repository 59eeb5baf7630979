"""``tire-estimation convert comma2k19|revs250lm|husky ...``: measured data to contract bags."""

from __future__ import annotations

import argparse
import importlib
import shlex
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tire_estimation.paths import check_new_path, out_argument


def _command(args: argparse.Namespace, dataset: str, source: Path) -> str:
    parts = ["tire-estimation", "convert", dataset, str(source), "--out", str(args.out)]
    if args.overwrite:
        parts.append("--overwrite")
    return shlex.join(parts)


def _convert(args: argparse.Namespace) -> int:
    """Run the dataset's converter on ``args.source`` and print what it wrote, its size and
    the time."""
    dataset = args.dataset
    check_new_path(args.out, "--out", overwrite=args.overwrite)
    module = importlib.import_module(f"tire_estimation.convert.{dataset}")
    convert: Callable[..., Path] = getattr(module, f"convert_{dataset}")
    t0 = time.perf_counter()
    command = _command(args, dataset, args.source)
    path = convert(args.source, args.out, overwrite=args.overwrite, command=command)
    print(f"wrote {path} ({_size_mb(path):.1f} MB in {time.perf_counter() - t0:.1f} s)")
    return 0


def _size_mb(path: Path) -> float:
    return sum(p.stat().st_size for p in Path(path).rglob("*") if p.is_file()) / 1e6


#: dataset (module ``tire_estimation.convert.<dataset>``, function ``convert_<dataset>``):
#: its help, the source argument's metavar and help
DATASETS: dict[str, tuple[str, str, str | None]] = {
    "comma2k19": (
        "a comma2k19 segment folder (CAN, IMU, u-blox GNSS, global_pose reference)",
        "SEGMENT_DIR",
        None,
    ),
    "revs250lm": (
        "the Revs Ferrari 250 LM text export (steering, IMU, INS velocities)",
        "DATA_DIR",
        None,
    ),
    "husky": (
        "robot_localization's Clearpath Husky test1.bag (ROS 1: drive odometry, IMU, GPS)",
        "DATA_DIR",
        "folder with test1.bag (or the bag)",
    ),
}


def add_convert_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``convert`` (``comma2k19``, ``revs250lm``, ``husky``) to the main CLI's sub-parsers."""
    conv = subparsers.add_parser("convert", help="convert measured data to a contract bag")
    sub = conv.add_subparsers(dest="dataset", required=True, metavar="DATASET")
    for dataset, (help_text, metavar, source_help) in DATASETS.items():
        p = sub.add_parser(dataset, help=help_text)
        p.add_argument("source", type=Path, metavar=metavar, help=source_help)
        p.add_argument("--out", required=True, type=out_argument, help="bag directory to create")
        p.add_argument("--overwrite", action="store_true", help="replace an existing bag")
        p.set_defaults(func=_convert)
    return conv
