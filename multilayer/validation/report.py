"""The validation report: one Markdown file holding an introduction, the section of each
case between ``<!-- section: NAME -->`` and ``<!-- /section -->`` markers, and a closing
text.  Regenerating some sections keeps the text of the others."""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable, Sequence
from pathlib import Path

from multilayer.validation.runs import Context, default_jobs

MARKED = re.compile(r"<!-- section: (\w+) -->\n(.*?)<!-- /section -->\n", re.S)
CONTENTS = "<!-- contents -->"
"""Where the introduction takes the list of the sections (:func:`contents`)."""
Section = Callable[[Context], str]


def cases() -> dict[str, Section]:
    """Section name -> the case that writes it, in report order."""
    from multilayer.validation.cases import SECTIONS

    return SECTIONS


def read(path: Path) -> dict[str, str]:
    """The sections of an existing report (none if it does not exist)."""
    return dict(MARKED.findall(path.read_text())) if path.is_file() else {}


def _anchor(title: str) -> str:
    """The anchor GitHub and the documentation site give a heading."""
    return re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")


def contents(sections: dict[str, str]) -> str:
    """A list linking the first heading of every section, in report order."""
    titles = [re.search(r"^## (.+)$", sections.get(name, f"## {name}"), re.M) for name in cases()]
    return "\n".join(f"- [{t[1]}](#{_anchor(t[1])})" for t in titles if t)


def write(path: Path, intro: str, sections: dict[str, str], regenerate: str, outro: str = "") -> None:
    """The report: ``intro``, then every case's section between its markers (a placeholder
    naming ``regenerate``, the command, for a section never generated), then ``outro``;
    :data:`CONTENTS` in ``intro`` becomes the list of the sections."""
    body = [
        f"<!-- section: {name} -->\n"
        + sections.get(name, f"## {name}\n\nNot generated yet: run `{regenerate} {name}`.\n")
        + "<!-- /section -->\n"
        for name in cases()
    ]
    intro = intro.replace(CONTENTS, contents(sections))
    path.write_text(intro + "\n" + "\n".join(body) + (f"\n{outro}" if outro else ""))


def main(
    argv: Sequence[str] | None,
    *,
    description: str,
    report: Path,
    runs: Path,
    intro: str,
    command: str,
    outro: str = "",
) -> int:
    """Regenerate the sections named in ``argv`` (all by default) of ``report``; the figures
    go to ``figures/`` beside it and the runs to ``runs`` (reused while their scenario is
    unchanged)."""
    names = list(cases())
    parser = argparse.ArgumentParser(
        prog=command, description=description, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "sections",
        nargs="*",
        metavar="SECTION",
        help=f"sections to regenerate (default all): {', '.join(names)}",
    )
    parser.add_argument("-j", "--jobs", type=int, default=default_jobs(), help="parallel runs (default 2)")
    parser.add_argument("--runs", type=Path, default=runs, help=f"directory of the runs (default {runs})")
    parser.add_argument("-o", "--report", type=Path, default=report, help=f"the report (default {report})")
    args = parser.parse_args(argv)
    unknown = sorted(set(args.sections) - set(names))
    if unknown:
        parser.error(f"unknown section(s) {', '.join(unknown)}; accepted: {', '.join(names)}")
    if args.jobs < 1:
        parser.error(f"--jobs {args.jobs}: accepted: an integer >= 1")
    ctx = Context(runs=args.runs, figures=args.report.parent / "figures", jobs=args.jobs)
    sections = read(args.report)
    for name in args.sections or names:
        print(f"section {name} ...", flush=True)
        sections[name] = cases()[name](ctx)
        write(args.report, intro, sections, command, outro)
    for failure in ctx.failures:
        print(f"  run {failure}")
    print(f"wrote {args.report}")
    return 0
