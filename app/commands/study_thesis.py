"""``dualrgb study thesis``: the thesis' tables beside the project's figures (simulation.studies.thesis), as JSON, a
Markdown table (SUMMARY.md) and, with ``--doc PAGE``, the docs page's generated section between
``<!-- thesis:start -->`` and ``<!-- thesis:end -->``.

  dualrgb study thesis [--out DIR] [--budget full|small] [--json PATH] [--doc PAGE] [--no-virtual-lab]

``full`` (default) runs the thesis' budgets (PSO 200 particles x 10 iterations on all 630 pairs, the GA of
Algorithm 2) and captures Table 7.2's conditions in the virtual lab; ``small`` (what the tests run: a few seconds)
uses a short PSO and GA and the pixel-level capture simulation. Registered by app.commands.study (one hook).
"""
from __future__ import annotations

import argparse
import logging
import sys

from dualrgb.app.json_output import add_json_option

log = logging.getLogger(__name__)


def register(ss: argparse._SubParsersAction, out_option) -> None:
    q = ss.add_parser("thesis", help="the thesis' tables (5.1-9.2) beside this project's figures, both modes",
                      description="Reproduce the thesis' simulation and capture tables with the project's code, in "
                                  "the matching mode, and say why each figure differs.")
    out_option(q, "thesis")
    q.add_argument("--budget", choices=("full", "small"), default="full",
                   help="full: the thesis' PSO / GA budgets and virtual-lab captures (default); small: seconds")
    q.add_argument("--doc", metavar="PAGE",
                   help="write the Markdown table into the docs page PAGE (docs/explanation/figures.md) between "
                        "<!-- thesis:start --> and <!-- thesis:end -->")
    q.add_argument("--no-virtual-lab", action="store_true",
                   help="Table 7.2 from the pixel-level capture simulation instead of the virtual lab")
    add_json_option(q)
    q.set_defaults(func=main)


def _capture(args: argparse.Namespace):
    """The virtual lab's capture of a light set (app.captured_accuracy), unless asked not to or in a small run."""
    if args.no_virtual_lab or args.budget == "small":
        return None
    from dualrgb.app.captured_accuracy import captured_errors

    def capture(setup, W, exposures):
        return captured_errors(setup, W, exposures, repeats=2)

    return capture


def main(args: argparse.Namespace) -> int:
    from dualrgb import resources
    from dualrgb.app.json_output import write_json
    from dualrgb.app.terminal_progress import TerminalProgress
    from dualrgb.simulation.studies.common import StudyOutput
    from dualrgb.simulation.studies.thesis import ThesisConfig, load_thesis_tables, reproduce
    from dualrgb.simulation.studies.thesis_report import FORMAT, build_rows, markdown, report_json, write_readme

    cfg = ThesisConfig.small() if args.budget == "small" else ThesisConfig()
    with TerminalProgress("study thesis") as progress:
        result = reproduce(cfg, capture=_capture(args), progress=progress)
    tables = load_thesis_tables()["tables"]
    rows = build_rows(tables, result["figures"])
    table = markdown(rows, result, tables)
    out = StudyOutput(args.out if args.out is not None else resources.user_path("studies", "thesis"))
    data = report_json(result, rows, tables)
    out.write_json("thesis_reproduction.json", data)
    out.write_summary("The thesis' tables reproduced", table.splitlines())
    if args.json:
        write_json(args.json, FORMAT, data)
    if args.doc:
        write_readme(args.doc, table)
        print(f"wrote the table into {args.doc}", file=sys.stderr)
    if args.json != "-":
        print(table)
    print(f"wrote {len(out.files)} files to {out.folder}", file=sys.stderr)
    return 0
