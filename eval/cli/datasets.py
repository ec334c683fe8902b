"""``poibench dataset`` and ``poibench route-frames``: the detector's training data."""

from __future__ import annotations

import argparse

from eval.cli.args import non_negative_int, positive_int
from eval.detector.dataset import DISTANCE_DRAWS, HAZMAT_PER_SCENARIO, DatasetSpec
from eval.detector.route_frames import RouteFramesSpec


def register(sub: argparse._SubParsersAction) -> None:
    d = sub.add_parser("dataset", help="render a YOLO-format detection dataset from randomised scenarios")
    d.add_argument("--out", required=True, help="output folder (a rerun with the same settings resumes)")
    d.add_argument("--images", type=int, required=True, help="number of images")
    d.add_argument("--seed", type=int, default=0, help="seed of every scenario and view (default 0)")
    d.add_argument("--per-scenario", type=positive_int, default=40, help="images per scenario (default 40)")
    d.add_argument(
        "--val-every", type=positive_int, default=5, help="every Nth scenario is validation (default 5)"
    )
    d.add_argument(
        "--hazmat",
        type=non_negative_int,
        default=HAZMAT_PER_SCENARIO,
        help=f"hazmat placards per scenario (default {HAZMAT_PER_SCENARIO}; 16: every label in every scenario)",
    )
    d.add_argument(
        "--hazmat-on-floor",
        type=float,
        default=DatasetSpec.hazmat_on_floor,
        help=f"share of the placards laid face up on the floor (default {DatasetSpec.hazmat_on_floor}; "
        "trials keep theirs on walls)",
    )
    d.add_argument(
        "--hazmat-on-doors",
        type=non_negative_int,
        default=DatasetSpec.hazmat_on_doors,
        help=f"placards per scenario stuck on door faces, "
        f"two a door at most (default {DatasetSpec.hazmat_on_doors})",
    )
    d.add_argument(
        "--hazmat-in-crates",
        type=non_negative_int,
        default=DatasetSpec.hazmat_in_crates,
        help=f"placards per scenario moved into open crates on the floor (default {DatasetSpec.hazmat_in_crates})",
    )
    d.add_argument(
        "--hazmat-on-ramps",
        type=non_negative_int,
        default=DatasetSpec.hazmat_on_ramps,
        help=f"placards per scenario laid on ramps against their walls (default {DatasetSpec.hazmat_on_ramps})",
    )
    d.add_argument(
        "--hazmat-on-boards",
        type=non_negative_int,
        default=DatasetSpec.hazmat_on_boards,
        help="boards per scenario holding a placard with a QR code beside it "
        f"(default {DatasetSpec.hazmat_on_boards})",
    )
    d.add_argument(
        "--shadows",
        type=float,
        default=DatasetSpec.shadow_fraction,
        help=f"share of the scenarios whose lamps cast shadows (default {DatasetSpec.shadow_fraction}; "
        "trials have none, for their cost)",
    )
    d.add_argument(
        "--distance",
        choices=DISTANCE_DRAWS,
        default=DatasetSpec.distance_draw,
        help="how the camera's distance to its target is drawn over 0.3-5 m: uniform (default), or "
        "log-uniform (log: about 4 views in 10 closer than 1 m, as in hand-held photos)",
    )
    d.add_argument(
        "--free-roll",
        type=float,
        default=DatasetSpec.free_roll,
        help=f"share of views with the camera rolled anywhere in +-180 deg instead of +-5 deg "
        f"(default {DatasetSpec.free_roll}; hand-held photos show placards at any angle)",
    )
    d.add_argument(
        "--camera",
        choices=("random", "trial"),
        default="random",
        help="random: each image draws its colour camera from wide ranges (for training, default); "
        "trial: the trial's D435 defaults on a still camera (to compare renders with real photos)",
    )
    d.add_argument(
        "--floor-textures",
        type=float,
        default=DatasetSpec.floor_textures,
        help=f"share of the scenarios with a terrazzo, concrete, carpet or glazed tile floor "
        f"(default {DatasetSpec.floor_textures}; real photos show placards lying on such floors)",
    )
    d.add_argument(
        "--print-saturation",
        type=float,
        nargs=2,
        metavar=("MIN", "MAX"),
        default=DatasetSpec.print_saturation,
        help="fraction of a placard's colour saturation kept, drawn per placard (default %(default)s; "
        "real crops' median saturation is 60 against 88 rendered)",
    )
    d.add_argument(
        "--print-black",
        type=float,
        nargs=2,
        metavar=("MIN", "MAX"),
        default=DatasetSpec.print_black,
        help="a placard's ink black level (0-255), drawn per placard (default %(default)s: deeper "
        "and more washed out than the renders' own)",
    )
    d.add_argument(
        "--glossy",
        type=float,
        default=DatasetSpec.glossy_fraction,
        help=f"share of the placards on glossy paper (lamp highlights and glare; "
        f"default {DatasetSpec.glossy_fraction})",
    )
    d.add_argument(
        "--msaa",
        type=int,
        default=DatasetSpec.msaa,
        help=f"MSAA samples of the renders, 0 2 4 or 8 (default {DatasetSpec.msaa}; trials render with 0)",
    )
    d.add_argument(
        "--closeups",
        type=float,
        default=DatasetSpec.closeup_fraction,
        help=f"share of the views that are close-ups, the target a third of the image high, with motion "
        f"blur (default {DatasetSpec.closeup_fraction})",
    )
    d.add_argument(
        "--landolt-targets",
        type=int,
        default=DatasetSpec.landolt_targets,
        help=f"Landolt-C targets an RRL scenario, never labelled (no detector class; one on the placard board, "
        f"the rest by themselves; default {DatasetSpec.landolt_targets})",
    )
    d.add_argument(
        "--milk-crates",
        type=int,
        default=DatasetSpec.milk_crates,
        help=f"open plastic crates a scenario standing near placards, unlabelled (RRL mazes; "
        f"default {DatasetSpec.milk_crates})",
    )
    d.add_argument("--quiet", action="store_true", help="no progress bar")
    d.set_defaults(func=cmd_dataset)

    rf = sub.add_parser(
        "route-frames", help="training frames from the robot's tours through generated mazes, truth-labelled"
    )
    rf.add_argument("--out", required=True, help="output folder (a rerun with the same settings resumes)")
    rf.add_argument("--mazes", type=int, required=True, help="generated RRL mazes to tour")
    rf.add_argument("--every", type=int, default=10, help="one frame in this many (default 10: one a second)")
    rf.add_argument("--seed", type=int, default=0, help="seed of the mazes (default 0)")
    rf.add_argument(
        "--set",
        dest="settings",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a scenario setting every maze takes (repeatable), e.g. a suite's: lighting=dim",
    )
    rf.add_argument(
        "--mine",
        metavar="MODEL",
        help="keep the frames this detector errs on (hard-example mining): 'default' (the shipped pair) "
        "or a detector ONNX, with --mine-labels",
    )
    rf.add_argument("--mine-labels", metavar="LABELS", help="the label model of --mine MODEL (ONNX)")
    rf.add_argument(
        "--keep-easy",
        type=positive_int,
        help="with --mine: keep one in this many of the frames it gets right "
        f"(default {RouteFramesSpec.keep_easy})",
    )
    rf.add_argument("--quiet", action="store_true", help="no progress bar")
    rf.set_defaults(func=cmd_route_frames)


def cmd_dataset(args) -> int:
    from eval.detector.dataset import DatasetSpec, write_dataset
    from eval.progress import progress_bar

    spec = DatasetSpec(
        images=args.images,
        seed=args.seed,
        images_per_scenario=args.per_scenario,
        val_every=args.val_every,
        counts={**DatasetSpec.default_counts(), "hazmat": args.hazmat},
        hazmat_on_floor=args.hazmat_on_floor,
        hazmat_on_doors=args.hazmat_on_doors,
        hazmat_in_crates=args.hazmat_in_crates,
        hazmat_on_ramps=args.hazmat_on_ramps,
        hazmat_on_boards=args.hazmat_on_boards,
        shadow_fraction=args.shadows,
        distance_draw=args.distance,
        free_roll=args.free_roll,
        floor_textures=args.floor_textures,
        print_saturation=tuple(args.print_saturation),
        print_black=tuple(args.print_black),
        glossy_fraction=args.glossy,
        msaa=args.msaa,
        closeup_fraction=args.closeups,
        landolt_targets=args.landolt_targets,
        milk_crates=args.milk_crates,
        **({"camera": None, "blur_fraction": 0.0} if args.camera == "trial" else {}),
    )
    with progress_bar(total=spec.images, desc="dataset", unit="img", quiet=args.quiet) as bar:
        summary = write_dataset(spec, args.out, progress=bar.update)
    n = summary["images"]
    inst = summary["instances"]
    print(f"{args.out}: {n['train']} train and {n['val']} val images from {spec.n_scenarios} scenarios")
    print(f"{'class':26s} {'train':>6s} {'val':>6s}")
    for c in inst["train"]:
        print(f"{c:26s} {inst['train'][c]:6d} {inst['val'][c]:6d}")
    print(f"data.yaml, manifest.csv and classes.png in {args.out}")
    return 0


def cmd_route_frames(args) -> int:
    from eval.detector.route_frames import RouteFramesSpec, write_route_frames
    from eval.progress import progress_bar

    spec = RouteFramesSpec(
        mazes=args.mazes,
        seed=args.seed,
        every=args.every,
        settings=tuple(args.settings),
        mine=_mining_pair(args),
        **({} if args.keep_easy is None else {"keep_easy": args.keep_easy}),
    )
    with progress_bar(desc="frames", unit="frame", quiet=args.quiet) as bar:
        summary = write_route_frames(spec, args.out, progress=bar.update)
    print(
        f"{args.out}: {summary['frames']} frames of {spec.mazes} tours, {summary['frames_with_labels']} "
        f"with a labelled object ({summary['boxes']} boxes)"
    )
    if spec.mine is not None:
        kinds = ", ".join(f"{k} {n}" for k, n in summary["mistakes"].items()) or "none"
        print(f"{summary['frames_with_mistakes']} frames with a mistake of {spec.mine_files()[0]}: {kinds}")
    return 0


def _mining_pair(args) -> tuple[str, str] | str | None:
    """(detector, label model) of --mine, or 'default' for the shipped pair; a label model is needed."""
    from eval.detector.dataset import DatasetError
    from poi.models import SHIPPED

    if args.mine is None:
        for flag, value in (("--mine-labels", args.mine_labels), ("--keep-easy", args.keep_easy)):
            if value is not None:
                raise DatasetError(f"{flag} goes with --mine MODEL")
        return None
    if args.mine == SHIPPED:
        if args.mine_labels is not None:
            raise DatasetError("--mine-labels goes only with --mine FILE.onnx (--mine default brings its own)")
        return SHIPPED
    if not args.mine.endswith(".onnx"):
        raise DatasetError(f"--mine {args.mine}: expected 'default' or a detector ONNX file")
    if args.mine_labels is None:
        raise DatasetError(f"--mine {args.mine}: give its label model with --mine-labels")
    return args.mine, args.mine_labels  # the files themselves: RouteFramesSpec checks them
