"""``usdscene generate STRATEGY --setup SETUP -o DOC``: a balanced sequence document from a
camera setup (see ``usdscene.generate.sequences`` and ``docs/generating.md``)."""

from __future__ import annotations

import argparse

NAME = "generate"
HELP = "generate a sequence document (single-class, balanced, appearance, random, tracks) from a setup document"
ORDER = 8

_STRATEGIES = ("single-class", "balanced", "appearance", "random")  # usdscene.generate.sequences.STRATEGIES, without its import
_TRACKS = "tracks"  # usdscene.generate.motion: people and vehicles that move


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene generate`` arguments and options to ``parser``."""
    from usdscene.commands._arguments import add_split_arguments, fraction, non_negative_int, output_path, positive_int

    parser.add_argument("strategy", choices=(*_STRATEGIES, _TRACKS),
                        help="single-class: one class in one relation at every place it fits, per frame; "
                             "balanced: equal instance-frames per class, every fitting (class, relation, place) "
                             "at least once; appearance: balanced with random variants and colours; "
                             "random: the naive ablation, uniformly random classes at uniformly random places, "
                             "no balancing; tracks: people walking between entrances and vehicles driving into "
                             "and out of bays, one track per object")
    parser.add_argument("--setup", metavar="SETUP_DOC", required=True,
                        help="setup document: environment, cameras, lights, render settings, fixed objects")
    parser.add_argument("-o", "--output", type=output_path, metavar="DOC", required=True,
                        help="sequence document to write; the balance report goes to DOC.report.json")
    parser.add_argument("--frames", type=positive_int, default=None,
                        help="sequence length (balanced, appearance, random); default: what full coverage "
                             "needs with balanced")
    parser.add_argument("--objects-per-frame", type=positive_int, default=None,
                        help="generated objects per frame (balanced, appearance, random); default: the class count, "
                             "or what coverage within --frames needs")
    parser.add_argument("--seed", type=non_negative_int, default=0, help="random seed (default 0)")
    parser.add_argument("--classes", nargs="+", metavar="NAME", default=(),
                        help="object classes to place (default: every object class of the catalog)")
    parser.add_argument("--places", nargs="+", metavar="GLOB", default=(),
                        help="place name patterns to use, e.g. 'seat_*' 'bin_*' (default: every place)")
    parser.add_argument("--occupancy", type=fraction, default=0.0,
                        help="fraction of the seats with a passenger in each frame (default 0)")
    add_split_arguments(parser)  # written into the document; usdscene export uses it
    moving = parser.add_argument_group("tracks")
    moving.add_argument("--fps", type=_fps, default=None, help="frame rate of a tracks sequence (default 10)")
    moving.add_argument("--people", type=non_negative_int, default=0, help="walkers (tracks)")
    moving.add_argument("--standing", type=non_negative_int, default=0,
                        help="people standing for the whole sequence (tracks)")
    moving.add_argument("--vehicles", type=non_negative_int, default=0, help="vehicles (tracks)")
    moving.add_argument("--person-classes", nargs="+", metavar="NAME", default=(),
                        help="classes of the people (default: every class of the catalog with walk_* pose "
                             "variants or a person word in its name, rigid ones without a walk cycle too)")
    moving.add_argument("--vehicle-classes", nargs="+", metavar="NAME", default=(),
                        help="classes of the vehicles (default: the catalog's vehicle classes); each drives "
                             "towards its -Y, the catalog's front (usdscene assets add --forward-axis)")
    moving.add_argument("--motion", choices=("routes", "crowd"), default="routes",
                        help="routes: each walker on a drawn route between entrances (default); crowd: people "
                             "simulated by the pedestrian engine JuPedSim (pip install 'usdscene[crowd]')")
    crowd = parser.add_argument_group("tracks --motion crowd (places may say their own values: docs/generating.md)")
    crowd.add_argument("--density", type=_non_negative_float, default=0.0, metavar="P_PER_M2",
                       help="people per m² of walkable area, inside at frame 0 and kept (instead of --people)")
    crowd.add_argument("--arrivals", type=_non_negative_float, default=0.0, metavar="PER_MIN",
                       help="arrivals per minute at every entrance (a Poisson process)")
    crowd.add_argument("--queue-share", type=fraction, default=0.0, help="fraction of people who join a queue")
    crowd.add_argument("--service", type=_non_negative_float, default=6.0, metavar="PER_MIN",
                       help="people a queue releases per minute (default 6)")
    crowd.add_argument("--wait-share", type=fraction, default=0.0,
                       help="fraction of people who stand at a waiting place for a while")
    crowd.add_argument("--wait", type=_non_negative_float, nargs=2, default=(10.0, 60.0), metavar=("LOW_S", "HIGH_S"),
                       help="waiting time, drawn uniformly (default 10 60 s)")
    crowd.add_argument("--via-share", type=fraction, default=0.0, help="fraction of people who pass each waypoint")
    crowd.add_argument("--group-share", type=fraction, default=0.0,
                       help="fraction of arrivals who come in groups of 2-4 that keep together")
    crowd.add_argument("--conversations", type=non_negative_int, default=0,
                       help="circles of 2-3 people standing in conversation for the whole sequence")
    crowd.add_argument("--seated", type=non_negative_int, default=0, help="people sitting on the benches")


def _fps(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected frames per second, got {text!r}") from None
    if not 0.0 < value <= 1000.0:  # usdscene.document.model.MAX_FPS
        raise argparse.ArgumentTypeError(f"expected frames per second in (0, 1000], got {text!r}")
    return value


def _non_negative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value >= 0.0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return value


def _run_tracks(args: argparse.Namespace) -> int:
    from rich.console import Console

    from usdscene.generate.sequences import report_path

    if args.motion == "crowd":
        import sys

        if args.vehicles or args.standing:
            flag = "--vehicles" if args.vehicles else "--standing"
            print(f"usdscene generate: error: {flag} belongs to --motion routes (a crowd has --conversations)",
                  file=sys.stderr)
            return 2
        from usdscene.generate.crowd import CrowdOptions, generate_crowd_document

        options = CrowdOptions(frames=args.frames or 100, fps=args.fps or 10.0, seed=args.seed, people=args.people,
                               density_p_m2=args.density, arrivals_per_min=args.arrivals,
                               queue_share=args.queue_share, service_per_min=args.service,
                               wait_share=args.wait_share, wait_s=tuple(args.wait), via_share=args.via_share,
                               group_share=args.group_share, conversations=args.conversations, seated=args.seated,
                               person_classes=tuple(args.person_classes))
        report = generate_crowd_document(args.setup, args.output, options).report
    else:
        from usdscene.generate.motion import TrackOptions, generate_tracks_document

        options = TrackOptions(frames=args.frames or 100, fps=args.fps or 10.0, people=args.people,
                               vehicles=args.vehicles, standing=args.standing, seed=args.seed,
                               person_classes=tuple(args.person_classes), vehicle_classes=tuple(args.vehicle_classes))
        report = generate_tracks_document(args.setup, args.output, options).report
    console = Console(highlight=False, soft_wrap=True)
    console.print(f"wrote {args.output}: {report['frames']} frames at {report['fps']:g} fps "
                  f"({report['seconds']:g} s), {report['tracks']} tracks")
    for kind, stats in report["track_frames"].items():
        console.print(f"  {kind}: {stats['count']} tracks, {stats['min']:g}..{stats['max']:g} frames "
                      f"(mean {stats['mean']:g})")
    people = report["people_per_frame"]
    if people["count"]:
        console.print(f"  people per frame: {people['min']:g}..{people['max']:g} (mean {people['mean']:g})")
    for name, cam in report["cameras"].items():
        seen = cam["frames_in_view"]
        span = f", {seen['min']:g}..{seen['max']:g} frames each" if seen["count"] else ""
        console.print(f"  camera {name}: {cam['tracks_in_view']} tracks in view{span}")
    crowd = report.get("crowd")
    if crowd:
        queues = ", ".join(f"{name} up to {q['most_in_line']} in line, {q['released']} served"
                           for name, q in crowd["queues"].items())
        console.print(f"  crowd: {crowd['walkable_area_m2']:g} m² walkable, {crowd['people_at_frame_0']} people at "
                      f"frame 0, {crowd['groups']} groups, {crowd['waits']['started']} waits, {crowd['standing']} standing, "
                      f"{crowd['seated']} seated"
                      + (f"; queues: {queues}" if queues else ""))
    console.print(f"  report: {report_path(args.output)}")
    return 0


def run(args: argparse.Namespace) -> int:
    """``usdscene generate``: write a generated sequence document and its report; returns the exit status."""
    if args.strategy == _TRACKS:
        return _run_tracks(args)
    for flag, value in (("--fps", args.fps), ("--people", args.people), ("--standing", args.standing),
                        ("--vehicles", args.vehicles)):
        if value:
            import sys

            print(f"usdscene generate: error: {flag} belongs to the tracks strategy", file=sys.stderr)
            return 2
    from rich.console import Console

    from usdscene.generate.sequences import GenerateOptions, generate_document, report_path

    options = GenerateOptions(strategy=args.strategy, frames=args.frames, seed=args.seed,
                              classes=tuple(args.classes), place_patterns=tuple(args.places),
                              occupancy=args.occupancy, objects_per_frame=args.objects_per_frame,
                              split=args.split.text if args.split is not None else "",
                              split_seed=args.split_seed)
    result = generate_document(args.setup, args.output, options)
    report = result.report
    coverage = report["coverage"]
    console = Console(highlight=False, soft_wrap=True)
    console.print(f"wrote {args.output}: {report['frames']} frames, {report['objects']} objects, "
                  f"{report['instance_frames']} instance-frames, {report['images']} images")
    counts = {name: c["instance_frames"] for name, c in report["classes"].items()}
    placed = {name: n for name, n in counts.items() if name in report["generator"]["classes"]}
    if placed:
        console.print(f"  per class: {min(placed.values())}..{max(placed.values())} instance-frames "
                      f"over {len(placed)} classes")
    left_out = coverage.get("classes_fitting_nowhere", [])
    if left_out:
        console.print(f"  left out, fitting no selected place (as their orientation rule allows): "
                      f"{', '.join(left_out)}")
    single = coverage.get("classes_without_variants", [])
    if single:
        console.print(f"  one appearance only, so not varied: {', '.join(single)}")
    console.print(f"  coverage: {coverage['covered']} of {coverage['combinations']} (class, relation, place) "
                  f"combinations")
    if coverage["uncovered_count"]:
        console.print(f"  {coverage['uncovered_count']} not covered; --frames "
                      f"{coverage['frames_for_full_coverage']} would cover all")
    drawn = report.get("domain_randomization")
    if drawn:
        world_fields = sorted({k for values in drawn["world"].values() for k in values})
        sensor_fields = sorted({k for frames in drawn["sensors"].values() for values in frames.values() for k in values})
        parts = []
        if world_fields:
            parts.append(f"world per frame ({', '.join(world_fields)})")
        if sensor_fields:
            parts.append(f"sensors of {len(drawn['sensors'])} cameras per frame ({', '.join(sensor_fields)})")
        console.print(f"  drawn: {'; '.join(parts)}; the values are in the report's domain_randomization")
    console.print(f"  report: {report_path(args.output)}")
    return 0
