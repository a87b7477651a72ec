"""``contouring-ros paper``: a paper's scenarios run and our numbers printed beside the paper's, then its
claims measured (:mod:`contouring_ros.studies.claims`); or, with ``--readings``, each open reading's effect
(:mod:`contouring_ros.studies.readings`)."""
from __future__ import annotations

import sys

from .arguments import MAX_WORKERS, force_option, scheduler_option, whole
from ..errors import ConfigError

__all__ = ["HELP", "OUTPUTS", "add_arguments", "main"]

HELP = "run a paper's scenarios and print our numbers beside the paper's"
#: the options that name what the command writes
OUTPUTS = ("out",)


def add_arguments(parser) -> None:
    """The arguments of ``paper``."""
    parser.add_argument("paper", help="paper number with scenario files in config/ (e.g. 000, 003) or 'all'")
    parser.add_argument("--out", default="reports", help="folder for the Markdown report (default: reports/)")
    parser.add_argument("--graph", action="store_true", help="run each scenario through the node graph too")
    parser.add_argument("--no-maps", action="store_true",
                        help="write the claims report without computing the regime maps")
    parser.add_argument("--readings", action="store_true",
                        help="instead of the claims: each open reading's effect on every figure, the single reading "
                             "closest to the paper's figures and what explains the rest of each gap "
                             "(config/readings/paper<N>.yaml)")
    parser.add_argument("--workers", type=whole(1, MAX_WORKERS, "processes"),
                        help=f"processes for the claims and maps, 1 to {MAX_WORKERS} (default: one per core)")
    scheduler_option(parser)
    force_option(parser)


def _say(message: str) -> None:
    """A line of progress on stderr."""
    print(message, file=sys.stderr, flush=True)


def main(args) -> None:
    """Write the report of the paper ``args.paper`` (or of all), then its claims report (or its readings)."""
    from ..studies.paper import available_papers, write_report
    papers = available_papers()
    if args.paper != "all" and args.paper not in papers:
        raise ConfigError(f"paper {args.paper!r}: no scenario files config/paper{args.paper}_*.yaml "
                          f"(papers with scenarios: {', '.join(papers)}, or all)")
    _claim_outputs(args)
    chosen = papers if args.paper == "all" else [args.paper]
    text = "\n\n".join(_sections(args, chosen))
    print(text)
    print(f"wrote {write_report(text, args.paper, args.out, args.readings)}", file=sys.stderr)
    if args.readings:
        return
    _claims(args, chosen)


def _claim_outputs(args) -> None:
    """Claim the report and the claims report in ``--out`` (:mod:`contouring_ros.records.outputs`)."""
    from ..records import outputs
    out = outputs.active().claim_folder(args.out, "--out")
    outputs.active().claim(out / ("papers.md" if args.paper == "all" else f"paper{args.paper}.md"), outputs.REPORT,
                           "--out")
    outputs.active().claim(out / ("claims.md" if args.paper == "all" else f"claims_paper{args.paper}.md"),
                           outputs.REPORT, "--out")


def _sections(args, chosen: list) -> list:
    """The report's sections: each chosen paper's, followed with ``--readings`` by its readings' analysis."""
    from ..studies.paper import paper_report
    if args.readings:
        from ..studies.readings import analyse, readings_files, readings_report
        with_readings = {path.stem[5:] for path in readings_files()}
        if args.paper != "all" and args.paper not in with_readings:
            raise ConfigError(f"paper {args.paper}: no config/readings/paper{args.paper}.yaml (papers with "
                              f"readings: {', '.join(sorted(with_readings))})")
    sections = []
    for p in chosen:
        sections.append(paper_report(p, graph=args.graph, progress=_say))
        if args.readings and p in with_readings:
            _say(f"paper {p}: measuring its open readings")
            sections.append(readings_report(analyse(p, workers=args.workers)))
    return sections


def _claims(args, chosen: list) -> None:
    """Measure the claims of the chosen papers that have a claims file, and write their report."""
    from ..studies.claims_file import claim_files
    from ..studies.claims_report import claims_report, write_claims_report
    with_claims = [p for p in chosen if any(path.stem == f"paper{p}" for path in claim_files())]
    if with_claims:
        report = claims_report(with_claims, args.out, maps=not args.no_maps, workers=args.workers, progress=_say,
                               command=args.paper, scheduler=args.scheduler)
        name = "claims.md" if args.paper == "all" else f"claims_paper{args.paper}.md"
        print(f"wrote {write_claims_report(report, args.out, name)}", file=sys.stderr)
