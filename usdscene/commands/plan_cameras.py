"""``usdscene plan-cameras``: how many cameras, where, with which lens; then ``--verify``."""

from __future__ import annotations

import argparse

NAME = "plan-cameras"
HELP = ("design a camera system: the smallest set of cameras (position, aim, lens) that sees every "
        "target at the required image-detail class; --verify PLAN_DIR renders it and compares")
ORDER = 15


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene plan-cameras`` arguments and options to ``parser``."""
    from usdscene.commands._arguments import non_negative_int, output_path, positive_int

    parser.add_argument("--setup", metavar="SETUP_DOC",
                        help="OpenLABEL setup document (environment, lights, render; its cameras with --mounts setup)")
    parser.add_argument("-o", "--out", type=output_path, metavar="PLAN_DIR", help="plan folder to write")
    parser.add_argument("--verify", type=output_path, metavar="PLAN_DIR",
                        help="render the plan in PLAN_DIR with its targets as markers and compare with the prediction")
    parser.add_argument("--targets", metavar="SPEC", nargs="+", default=None,
                        help="PLACE_GLOB:REGION,... (e.g. 'seat_*:on,below,in_front') or "
                             "box:NAME:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX in metres (default: every region of every place)")
    parser.add_argument("--mounts", default="auto", metavar="auto|setup|FILE",
                        help="'auto': ceiling and wall positions every --spacing metres, poles and facades in the "
                             "open air, and the environment's mount_* nodes; 'setup': re-score the setup document's "
                             "own cameras; FILE: a JSON list of mounts (position_m, optional aims / look_at_m)")
    parser.add_argument("--spacing", type=float, default=0.8, metavar="M",
                        help="ceiling and wall mount grid spacing in metres (0.8)")
    parser.add_argument("--pole-heights", type=float, nargs="*", default=None, metavar="M",
                        help="camera heights of open-air poles and facade mounts above the ground in metres "
                             "(4 6; none for no poles)")
    parser.add_argument("--pole-spacing", type=float, default=4.0, metavar="M",
                        help="grid spacing of open-air poles in metres (4)")
    parser.add_argument("--lenses", metavar="FILE", help="lens catalog JSON extending the shipped one")
    parser.add_argument("--lens", nargs="+", metavar="NAME", help="catalog lenses to try (default: all)")
    parser.add_argument("--k", type=positive_int, default=1, help="cameras each target needs (1)")
    parser.add_argument("--dori", default=None, metavar="CLASS",
                        help="required image-detail level: IEC 62676-4:2025 overview, outline, discern (default), "
                             "perceive, characterize, validate, scrutinize; with --standard 2015 monitor, detect, "
                             "observe (default), recognise, identify, inspect")
    parser.add_argument("--standard", default="2025", choices=("2015", "2025"),
                        help="edition of IEC 62676-4 whose image-detail table is used (2025)")
    parser.add_argument("--dori-table", metavar="FILE",
                        help="image-detail table JSON replacing the standard's (a site's own requirement)")
    parser.add_argument("--occluders", default="worst-case", metavar="worst-case|setup",
                        help="what blocks the views: a passenger in every seat (worst-case) or the setup's objects")
    parser.add_argument("--min-visible", type=float, default=0.25, metavar="FRACTION",
                        help="fraction of a target's points a camera must see (0.25)")
    parser.add_argument("--aims", type=non_negative_int, default=4, help="target-cluster aims per mount (4)")
    parser.add_argument("--cell", type=float, default=5.0, metavar="M",
                        help="target regions longer than this are split into cells no longer than this, in metres "
                             "(5; coverage is then the share of floor area seen)")
    parser.add_argument("--target-spacing", type=float, default=0.2, metavar="M",
                        help="spacing of the sample points in each target in metres (0.2)")
    parser.add_argument("--max-memory", type=float, default=6.0, metavar="GB",
                        help="refuse, before casting rays, a request whose (camera, target) pairs would take more "
                             "than this (6)")
    parser.add_argument("--time-limit", type=float, default=60.0, metavar="S", help="MILP time limit in seconds (60)")
    parser.add_argument("--zone", type=float, default=0.0, metavar="M",
                        help="plan the floor in square zones of this side in metres, one program each, cameras "
                             "shared across zone borders (0: the whole floor in one program)")
    parser.add_argument("--verify-scale", type=float, default=0.5, metavar="S",
                        help="render size of --verify relative to the cameras' resolution (0.5)")
    parser.add_argument("--verify-samples", type=positive_int, default=1, metavar="N", help="Cycles samples of --verify (1)")
    parser.add_argument("--verify-cameras", type=positive_int, default=None, metavar="N",
                        help="--verify renders a random sample of N of the plan's cameras (default: all)")
    parser.add_argument("--verify-targets", type=positive_int, default=None, metavar="N",
                        help="--verify checks a random sample of N targets in view of each rendered camera "
                             "(default: all)")
    parser.add_argument("--verify-seed", type=non_negative_int, default=0, metavar="SEED",
                        help="seed of the --verify sample (0)")
    parser.add_argument("--marker-radius", type=float, default=0.02, metavar="M",
                        help="radius of the target markers of --verify in metres (0.02; larger for distant "
                             "open-air targets, so that a marker covers a pixel)")


def run(args: argparse.Namespace) -> int:
    """``usdscene plan-cameras``: plan (or verify) the cameras of a setup; returns the exit status."""
    import collections

    from rich.console import Console

    console = Console(highlight=False, soft_wrap=True, emoji=False, markup=False)
    if args.verify:
        if args.setup or args.out:
            return _usage("--verify PLAN_DIR takes no --setup or -o")
        from usdscene.design.plan_verify import VERIFY_DIR, verify_plan

        result = verify_plan(args.verify, resolution_scale=args.verify_scale, samples=args.verify_samples,
                             marker_radius_m=args.marker_radius, cameras=args.verify_cameras,
                             targets_per_camera=args.verify_targets, seed=args.verify_seed)
        sample = result.report["summary"]["sample"]
        console.print(f"verified {args.verify}: {result.agreeing}/{result.pairs} (camera, target) pairs agree "
                      f"({100 * result.agreement:.1f} %, visible fractions within {result.tolerance:g}); "
                      f"{result.points_agreeing}/{result.points} target points agree")
        console.print(f"  sample:  {sample['cameras']} of {sample['of_cameras']} cameras, {sample['targets']} of "
                      f"{sample['of_targets']} targets (seed {sample['seed']}); agreement {100 * result.interval.low:.1f}"
                      f"-{100 * result.interval.high:.1f} % at {100 * result.interval.confidence:g} % confidence "
                      f"(exact binomial interval)")
        console.print(f"  render {result.seconds['render']:.1f} s; details in {args.verify}/{VERIFY_DIR}/")
        return 0
    if not args.setup or not args.out:
        return _usage("plan-cameras needs --setup SETUP_DOC and -o PLAN_DIR (or --verify PLAN_DIR)")
    from usdscene.design.camera_design import plan_cameras

    request = plan_request(args)
    with _ProgressBar(console) as bar:
        result = plan_cameras(request, args.out, progress=bar.update)
    s = result.coverage["summary"]
    sel = result.selection
    console.print(f"planned {s['cameras']} cameras from {s['candidates']} candidates ({s['mounts']} mounts) "
                  f"for {s['targets']} targets in {sum(result.seconds.values()):.1f} s")
    console.print(f"  solver:  {sel.method}{f' ({sel.zones} zones)' if sel.zones > 1 else ''}"
                  f"{' (optimal)' if sel.optimal else ''}, lower bound {sel.lower_bound}, "
                  f"gap {100 * sel.gap:.1f} %, greedy {sel.greedy_size}")
    request = result.coverage["request"]
    console.print(f"  covered: {s['targets_covered']}/{s['targets']} targets by >= {args.k} camera(s) at >= "
                  f"{request['dori']} ({request['standard']})")
    for reason, n in s.get("mounts_left_out", {}).items():
        console.print(f"  no mount: {n} {reason}")
    area = s["floor_area"]
    if area["total_m2"] > 0:
        console.print(f"  floor:   {area['covered_m2']:.1f} of {area['total_m2']:.1f} m² seen at the level "
                      f"({100 * area['share']:.1f} %): " + ", ".join(
                          f"{name} {100 * p['share']:.1f} %" for name, p in list(area["places"].items())[:8])
                      + (" ..." if len(area["places"]) > 8 else ""))
    if s["holes"]:
        console.print(f"  holes:   {len(s['holes'])}: {', '.join(s['holes'][:12])}{' ...' if len(s['holes']) > 12 else ''}")
    why = s["why_uncoverable"]
    if why:
        counts = collections.Counter(w["reason"] for w in why.values())
        console.print(f"  no candidate covers {len(why)} target(s): "
                      + ", ".join(f"{n} {reason}" for reason, n in counts.most_common()))
        for name, w in list(why.items())[:12]:
            console.print(f"    {name}: {w['reason']}; best class any candidate reaches: {w['best_dori'] or 'none'}")
        if len(why) > 12:
            console.print(f"    ... {len(why) - 12} more in {args.out}/coverage.json (summary.why_uncoverable)")
    console.print("  steps:   " + ", ".join(f"{k} {v:.1f} s" for k, v in result.seconds.items())
                  + f" (ray casting: {result.backend})")
    console.print(f"  outputs: {args.out}/cameras.openlabel.json, coverage.json, coverage.png")
    console.print(f"  next:    usdscene plan-cameras --verify {args.out}")
    return 0


def plan_request(args: argparse.Namespace):
    """The :class:`usdscene.design.plan_request.PlanRequest` of parsed arguments (checked)."""
    from usdscene.design.plan_request import PlanRequest

    return PlanRequest.build(args.setup, targets=args.targets, mounts=args.mounts, spacing_m=args.spacing,
                             lenses_file=args.lenses, lens_names=args.lens, k=args.k, dori=args.dori,
                             dori_table_file=args.dori_table, standard=args.standard, occluders=args.occluders,
                             min_visible=args.min_visible, aims=args.aims, time_limit_s=args.time_limit,
                             pole_heights_m=args.pole_heights, pole_spacing_m=args.pole_spacing, cell_m=args.cell,
                             target_spacing_m=args.target_spacing, max_memory_gb=args.max_memory,
                             zone_m=args.zone)


class _ProgressBar:
    """A ``rich`` bar on stderr for the long steps of planning: the stage, cameras scored and
    the time left."""

    def __init__(self, console) -> None:
        self._console = console
        self._progress = None
        self._task = None

    def __enter__(self) -> "_ProgressBar":
        import sys

        if sys.stderr.isatty():
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

            self._progress = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                      TextColumn("cameras"), TimeRemainingColumn(),
                                      console=Console(stderr=True), transient=True)
            self._progress.__enter__()
        return self

    def update(self, stage: str, done: int, total: int) -> None:
        if self._progress is None:
            return
        if self._task is None:
            self._task = self._progress.add_task(stage, total=total)
        self._progress.update(self._task, description=stage, completed=done, total=total)

    def __exit__(self, *exc) -> None:
        if self._progress is not None:
            self._progress.__exit__(*exc)


def _usage(message: str) -> int:
    import sys

    print(f"usdscene plan-cameras: error: {message}", file=sys.stderr)
    return 2
