"""The ``tire-estimation`` command line: simulate, inspect, replay and convert bags.

Every failure the package anticipates (bad arguments, bad path, corrupt bag, absurd
vehicle.yaml, unknown scenario, misspelled key, unwritable ``--out``, ...) ends in one line
``tire-estimation: error: ...`` of at most :data:`MAX_LINE` characters on stderr and exit
status 2, never in a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import difflib
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, NoReturn

import yaml

from tire_estimation import __version__
from tire_estimation.core import yamlio
from tire_estimation.errors import TireEstimationError, one_line
from tire_estimation.paths import REPLAY_REPORT_FILES, out_argument

EXIT_ERROR = 2
#: longest error line
MAX_LINE = 300


class Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line (no usage block) and name the nearest option
    of a misspelled one."""

    def error(self, message: str) -> NoReturn:
        if message.startswith("unrecognized arguments:"):
            owners: dict[str, list[str]] = {}
            for command, option in _option_strings(self):
                owners.setdefault(option, []).append(command)
            for word in message.split(":", 1)[1].split():
                name = word.split("=")[0]
                if not word.startswith("-"):
                    continue
                if name in owners:
                    # a valid option of other sub-commands (argparse names none)
                    cmds = owners[name]
                    more = f" and {len(cmds) - 2} more" if len(cmds) > 2 else ""
                    message += (
                        f" ({name} is an option of {', '.join(cmds[:2])}{more}, not of this "
                        "command)"
                    )
                    break
                near = difflib.get_close_matches(name, sorted(owners), n=1, cutoff=0.75)
                if near:
                    message += f" (did you mean {near[0]}?)"
                    break
        text = f"{self.prog}: error: {message} (see {self.prog} --help)"
        self.exit(EXIT_ERROR, one_line(text, MAX_LINE) + "\n")


def _option_strings(parser: argparse.ArgumentParser) -> Iterator[tuple[str, str]]:
    """(command, option string) of the long options of ``parser`` and of all its
    sub-commands (an option reported unrecognized by the main parser may be a sub-command's
    when it was given to another one)."""
    for action in parser._actions:
        yield from ((parser.prog, o) for o in action.option_strings if o.startswith("--"))
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield from _option_strings(sub)


def parse_key_value(text: str) -> tuple[str, Any]:
    """``key=value`` with the value parsed as YAML (numbers, booleans, lists)."""

    if "=" not in text:
        raise argparse.ArgumentTypeError(f"expected key=value, got {text!r}")
    key, raw = text.split("=", 1)
    try:
        return key.strip(), yamlio.safe_load(raw)
    except yaml.YAMLError as exc:
        raise argparse.ArgumentTypeError(f"{key.strip()}: {yamlio.describe(exc)}") from exc


def _cmd_simulate(args: argparse.Namespace) -> int:
    import dataclasses

    from tire_estimation.bag.writer import write_sim_bag
    from tire_estimation.core.validation import unknown_key_reason
    from tire_estimation.core.vehicle import load_vehicle_yaml
    from tire_estimation.errors import ConfigError
    from tire_estimation.paths import check_new_path
    from tire_estimation.sim import SensorConfig, simulate

    options = dict(args.option or [])
    sensor_fields = {f.name for f in dataclasses.fields(SensorConfig)}
    sensor_values = dict(args.sensor or [])
    for key, value in sensor_values.items():
        if key not in sensor_fields:
            reason = unknown_key_reason(key, sensor_fields, what="sensor setting")
            raise ConfigError(f"--sensor {key}", value, reason)
        if isinstance(value, list):
            sensor_values[key] = tuple(value)
    sensors = SensorConfig(**sensor_values)
    vehicle = load_vehicle_yaml(args.vehicle) if args.vehicle is not None else None
    check_new_path(args.out, "--out", overwrite=args.overwrite)
    t0 = time.perf_counter()
    result = simulate(
        args.scenario,
        seed=args.seed,
        minutes=args.minutes,
        sensors=sensors,
        vehicle=vehicle,
        **options,
    )
    t1 = time.perf_counter()
    path = write_sim_bag(result, args.out, overwrite=args.overwrite)
    t2 = time.perf_counter()
    print(
        f"wrote {path} ({result.scenario}, seed {result.seed}, {result.duration_s / 60:.1f} min "
        f"simulated in {t1 - t0:.1f} s, written in {t2 - t1:.1f} s)"
    )
    return 0


def _cmd_scenarios(_: argparse.Namespace) -> int:
    from tire_estimation.sim import SCENARIOS

    width = max(len(name) for name in SCENARIOS)
    for name, description in SCENARIOS.items():
        print(f"{name:<{width}}  {description}")
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    from tire_estimation.bag.describe import describe_bag

    print(describe_bag(args.bag))
    return 0


def _cmd_replay(args: argparse.Namespace) -> int:
    from tire_estimation.fleet import is_fleet
    from tire_estimation.replay import run_replay

    options = {
        "config_path": args.config,
        "plots": not args.no_plots,
        "stiffness": False if args.no_stiffness else None,
        "rank_effects": args.rank_effects,
        "rank_seeds": args.rank_seeds,
        "write_config": args.write_config,
    }
    if is_fleet(args.bag):
        return _replay_fleet(args, options)
    if args.scheduler is not None or args.workers is not None:
        option = "--scheduler" if args.scheduler is not None else "--workers"
        return fail(f"{option} replays a fleet: give several bags or a directory of bags")
    report = run_replay(args.bag[0], args.out, progress=not args.no_progress, **options)
    print(report.summary())
    return 0


def _replay_fleet(args: argparse.Namespace, options: dict[str, Any]) -> int:
    from tire_estimation.fleet import run_fleet

    def progress(row: dict[str, Any], done: int, total: int) -> None:
        if args.no_progress:
            return
        if row["status"] == "ok":
            what = f"ok ({row['duration_s']:.0f} s of data in {row['wall_s']:.1f} s)"
        else:
            what = f"FAILED: {row['error']}"
        print(f"[{done}/{total}] {row['bag']}: {what}", flush=True)

    if args.workers is not None and args.workers < 1:
        return fail(f"--workers={args.workers}: must be >= 1")
    result = run_fleet(
        args.bag,
        args.out,
        options,
        scheduler=args.scheduler,
        n_workers=args.workers,
        progress=progress,
    )
    print(f"pooled table: {result.files[1]} ({result.files[0].name})")
    if result.failed:
        failed = f"{len(result.failed)} of {len(result.rows)} bags failed"
        return fail(f"{failed} (see {result.files[1]})")
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from tire_estimation.atomic_io import atomic_write_text
    from tire_estimation.core.vehicle import load_vehicle_yaml
    from tire_estimation.export import read_learned_radii, render
    from tire_estimation.paths import check_new_path

    if args.out is not None:
        check_new_path(args.out, "--out", overwrite=args.overwrite)
    vehicle = load_vehicle_yaml(args.vehicle) if args.vehicle is not None else None
    learned = read_learned_radii(args.source, vehicle, args.tire_set)
    text = render(learned, args.format, args.controller)
    if args.out is None:
        print(text, end="")
    else:
        atomic_write_text(args.out, text)
        print(f"wrote {args.out} ({args.format}, from the {learned.source} {args.source})")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (exposed for tests and documentation)."""
    parser = Parser(
        prog="tire-estimation",
        description="Online tire radius/stiffness estimation: simulate, replay, inspect bags.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    sim = sub.add_parser("simulate", help="write a simulated evaluation bag (MCAP)")
    sim.add_argument("scenario", help="scenario name (see `tire-estimation scenarios`)")
    sim.add_argument("--out", required=True, type=out_argument, help="bag directory to create")
    sim.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    sim.add_argument("--minutes", type=float, default=None, help="duration (scenario default)")
    sim.add_argument(
        "--option",
        action="append",
        type=parse_key_value,
        metavar="KEY=VALUE",
        help="scenario option, repeatable (e.g. deflate_wheel=wheel_rr)",
    )
    sim.add_argument(
        "--sensor",
        action="append",
        type=parse_key_value,
        metavar="KEY=VALUE",
        help="sensor setting (SensorConfig field), repeatable (e.g. gnss_rate_hz=1)",
    )
    sim.add_argument(
        "--vehicle",
        default=None,
        metavar="YAML",
        help="vehicle.yaml of the simulated vehicle (default: the project's mid-size car); "
        "written into the bag",
    )
    sim.add_argument("--overwrite", action="store_true", help="replace an existing bag")
    sim.set_defaults(func=_cmd_simulate)

    scen = sub.add_parser("scenarios", help="list the simulation scenarios")
    scen.set_defaults(func=_cmd_scenarios)

    info = sub.add_parser("info", help="print what a bag holds (topics, counts, vehicle)")
    info.add_argument("bag", type=Path)
    info.set_defaults(func=_cmd_info)

    rep = sub.add_parser(
        "replay", help="run the estimators over a bag (or a fleet's bags) and write a report"
    )
    rep.add_argument(
        "bag",
        type=Path,
        nargs="+",
        help="a bag; several bags, or a directory of bags, replay a fleet on Dask: a report "
        "per bag in a subdirectory of --out, and the pooled fleet.csv and fleet.md",
    )
    rep.add_argument(
        "--out",
        required=True,
        type=out_argument,
        help="report directory; a run first removes an earlier run's metrics.json and plots "
        "from it, and a failed run leaves none",
    )
    rep.add_argument("--config", type=Path, default=None, help="estimator parameters (YAML)")
    rep.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    rep.add_argument(
        "--no-progress", action="store_true", help="no progress bar (fleet: no progress lines)"
    )
    rep.add_argument(
        "--rank-effects",
        action="store_true",
        help="rank and size the switchable unmodelled effects by re-running the radius MPF "
        "with each switched on (profile likelihood; about 20 re-runs of the bag)",
    )
    rep.add_argument(
        "--rank-seeds",
        type=int,
        default=1,
        metavar="N",
        help="with --rank-effects: run the base model and every re-run with N filter seeds "
        "(seed .. seed+N-1) and profile their mean likelihood (N times the re-runs; default 1)",
    )
    rep.add_argument(
        "--write-config",
        type=Path,
        default=None,
        metavar="FILE",
        help="add the effects found to the model, write them as a params file that --config "
        "and the node's --params-file load, and report the fit before and after: without "
        "--rank-effects the significant effects of the sensor agreement at their sizes (one "
        "re-run); with it, one at a time at its profile estimate, ranking the rest again "
        "(at most 3)",
    )
    rep.add_argument(
        "--no-stiffness",
        action="store_true",
        help="do not run the stiffness MPF (and its linear-KF baseline), whatever the "
        "configuration's stiffness_enabled says",
    )
    rep.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="fleet: a running Dask scheduler (e.g. tcp://host:8786; connect only to "
        "schedulers you trust; its workers must see the bags and --out) instead of a local "
        "cluster on 127.0.0.1",
    )
    rep.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="fleet: worker processes of the local cluster (default: one per bag, at most "
        "one per CPU)",
    )
    rep.set_defaults(func=_cmd_replay)

    exp = sub.add_parser(
        "export",
        help="write the learned radii as diff_drive_controller or vehicle parameters (YAML)",
    )
    exp.add_argument(
        "source", type=Path, help="a node's persistence file or a replay's metrics.json"
    )
    exp.add_argument(
        "--vehicle",
        type=Path,
        default=None,
        help="vehicle.yaml of the vehicle (nominal radius, name); required for a persistence "
        "file, for a metrics.json the replayed bag's vehicle.yaml by default",
    )
    exp.add_argument(
        "--tire-set",
        default="default",
        metavar="ID",
        help="tire set the persisted radii must belong to (the node's tire_set_id; default "
        "'default')",
    )
    exp.add_argument(
        "--format",
        choices=("diff_drive", "vehicle"),
        default="diff_drive",
        help="diff_drive: ros2_control diff_drive_controller parameters (wheel_radius, "
        "left/right_wheel_radius_multiplier of wheel_rl/wheel_rr); vehicle: per-wheel "
        "effective radius, std, multiplier and the speed scale factor (default diff_drive)",
    )
    exp.add_argument(
        "--controller",
        default="diff_drive_controller",
        metavar="NAME",
        help="with --format diff_drive: the controller's name, the YAML's top-level key",
    )
    exp.add_argument(
        "--out", type=out_argument, default=None, help="YAML file to write (default: stdout)"
    )
    exp.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    exp.set_defaults(func=_cmd_export)

    try:  # measured-data converters (tire_estimation.convert) register their own sub-commands
        from tire_estimation.convert.cli import add_convert_parser
    except ImportError:
        pass
    else:
        add_convert_parser(sub)
    try:  # evaluation campaigns (ECE R-64, calibration study)
        from tire_estimation.evaluation.campaign import add_campaign_parser
    except ImportError:
        pass
    else:
        add_campaign_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``tire-estimation`` console script."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        if exc.code:  # a replay command line that does not parse leaves no report either
            _remove_replay_report(sys.argv[1:] if argv is None else list(argv))
        raise
    func: Callable[[argparse.Namespace], int] = args.func
    try:
        return func(args)
    except TireEstimationError as exc:
        return fail(str(exc))
    except OSError as exc:  # a file system failure the checks did not foresee (disk full, ...)
        where = f" {exc.filename}" if exc.filename else ""
        return fail(f"{exc.strerror or type(exc).__name__}:{where}")
    except KeyboardInterrupt:
        print("tire-estimation: interrupted", file=sys.stderr)
        return 130


def _remove_replay_report(argv: list[str]) -> None:
    """Remove the report files from the ``--out`` of a ``replay`` command line that did not
    parse (as a run that fails removes them); nothing when it names no directory."""
    if not argv or argv[0] != "replay":
        return
    for i, word in enumerate(argv):
        name, eq, value = word.partition("=")
        if len(name) < 3 or not "--out".startswith(name):  # argparse takes --o, --ou
            continue
        value = value if eq else (argv[i + 1] if i + 1 < len(argv) else "")
        for report in REPLAY_REPORT_FILES if value.strip() else ():
            with contextlib.suppress(OSError):  # not a directory, a name too long, ...
                (Path(value) / report).unlink(missing_ok=True)


def fail(message: str) -> int:
    """Print ``tire-estimation: error: message`` as one line on stderr; return the exit status."""
    print(one_line(f"tire-estimation: error: {message}", MAX_LINE), file=sys.stderr)
    return EXIT_ERROR


if __name__ == "__main__":
    raise SystemExit(main())
