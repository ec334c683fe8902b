"""``poibench score REPORT.csv --truth TRUTH.csv [--rules PRESET|FILE] [--json]``.

Prints the score tables (or the JSON report) to stdout: points, or the map error of a
``scoring: map_error`` preset (turtlebot). Exit status 0 whenever
scoring succeeded, even when rows could not be read (they are listed and scored
as false reports); 2 with a one-line ``poibench score: error: ...`` on stderr
when an input cannot be read at all or the rules are invalid.
"""

from __future__ import annotations

import argparse
import json
import sys

from eval.cli.args import RULES_HELP
from eval.scoring.report import format_tables, to_json_dict
from eval.scoring.rules import PRESETS, RulesError, load_rules
from eval.scoring.scorer import score
from eval.scoring.truth import TruthFileError, read_truth_file
from poi.core.poi_file import PoiFileError, read_poi_file

EXIT_OK = 0
EXIT_INPUT_ERROR = 2


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add the ``score`` subcommand (its ``func`` default is :func:`run`)."""
    parser = subparsers.add_parser(
        "score",
        help="score a POI report against ground truth",
        description="Score a POI report (competition CSV) against a ground-truth POI file.",
    )
    parser.add_argument("report", metavar="REPORT.csv", help="the POI report to score")
    parser.add_argument("--truth", required=True, metavar="TRUTH.csv", help="ground truth (POI file, mode GT)")
    parser.add_argument(
        "--rules",
        default="ex3",
        metavar="|".join(PRESETS) + "|FILE",
        help=f"{RULES_HELP} (default: ex3)",
    )
    parser.add_argument("--json", action="store_true", help="print the score report as JSON")
    parser.set_defaults(func=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """Score and print; returns the exit status (0 scored, 2 unreadable input or rules)."""
    try:
        rules = load_rules(args.rules)
        reports = read_poi_file(args.report)
        truth = read_truth_file(args.truth)
    except (PoiFileError, RulesError, TruthFileError) as exc:
        message = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f"poibench score: error: {message}", file=sys.stderr)
        return EXIT_INPUT_ERROR
    gt = sum(r.mode == "GT" for r in reports.rows)
    if gt:  # scorable, but a report of the truth's mode is most likely a truth file
        note = f"{args.report}: {gt} of {len(reports.rows)} report rows are of mode GT, the truth's"
        print(f"note: {note}", file=sys.stderr)
    result = score(reports, truth, rules)
    if args.json:
        json.dump(to_json_dict(result), sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        sys.stdout.write(format_tables(result))
    return EXIT_OK
