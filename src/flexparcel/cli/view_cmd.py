"""``flexparcel view``: the 3-D viewer page of a results folder, ``DIR/view.html``
(:mod:`flexparcel.viz.viewer`), for a run written before viewers existed or with another
size budget; and, for a folder with ``responses.json``, its report ``DIR/report.html``
again (:mod:`flexparcel.viz.report`), which embeds the viewer."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "view",
        help="write a results folder's 3-D viewer (DIR/view.html, opens in a browser)",
        description="Write DIR/view.html for the results folder DIR (the --out of flexparcel "
        "run): one self-contained HTML file (nothing is fetched when it is opened) with the "
        "packaging, contents, belt and deflectors in 3-D, animated over the saved frames, "
        "coloured by displacement, speed, membrane strain, consignment or contact force where "
        "the run recorded it. Frames are subsampled to stay within --max-mb; the page says so. "
        "DIR/report.html, the run's report that embeds the viewer, is written again too. "
        "flexparcel run writes both by itself.",
    )
    p.add_argument("results", type=Path, metavar="DIR", help="results folder (with results.npz)")
    p.add_argument("--out", type=Path, default=None, metavar="FILE.html",
                   help="where to write the page (default DIR/view.html)")  # fmt: skip
    p.add_argument("--max-mb", type=float, default=None, metavar="MB",
                   help="size budget of the page [MB] (default 20)")  # fmt: skip
    p.add_argument("--max-frames", type=int, default=None, metavar="N",
                   help="show at most N frames (evenly spaced, first and last kept)")  # fmt: skip
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    try:
        from flexparcel.viz.viewer import DEFAULT_MAX_MB, ViewerError, write_viewer
    except ImportError as exc:
        print(f"flexparcel view: error: the viewer needs plotly ({exc}); install "
              "'flexparcel[io]'", file=sys.stderr)  # fmt: skip
        return 2
    max_mb = DEFAULT_MAX_MB if args.max_mb is None else args.max_mb
    if not max_mb > 0:
        raise ValueError(f"--max-mb must be > 0, got {args.max_mb:g}")
    if args.max_frames is not None and args.max_frames < 2:
        raise ValueError(f"--max-frames must be >= 2, got {args.max_frames}")
    try:
        path = write_viewer(args.results, args.out, max_mb=max_mb, max_frames=args.max_frames)
    except ViewerError as exc:
        print(f"flexparcel view: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # an unwritable --out, say
        print(f"flexparcel view: error: {exc}", file=sys.stderr)
        return 2
    size = path.stat().st_size / 1e6
    print(f"viewer: {path} ({size:.1f} MB); open it in a web browser")
    if args.out is None and (args.results / "responses.json").is_file():
        _rewrite_report(args.results)
    return 0


def _rewrite_report(folder: Path) -> None:
    """DIR/report.html again (it embeds the viewer); a note, not a failure, where the
    folder's responses.json cannot be reported on (the viewer is written)."""
    from flexparcel.viz.report import ReportError, write_report

    try:
        print(f"report: {write_report(folder)}")
    except (ReportError, OSError) as exc:
        print(f"flexparcel view: report not written: {exc}", file=sys.stderr)
