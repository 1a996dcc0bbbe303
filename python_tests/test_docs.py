"""The README and docs/ hold together (issue 25, "Structure").

* README.md stays under 12,000 characters, tells discovery in about ten lines and links
  docs/discovery.md, and lists every document of docs/ (one line each);
* every relative link in README.md and docs/*.md names a file or folder that exists, and an
  anchor (``file.md#heading``) names a heading of that file;
* the two commands of a new user are the scripts the repository has, and the test command is the
  one CI runs (.ci/run);
* each example of the command-line tour parses with tether's own parser and names traces that
  exist.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
README_LIMIT = 12_000
DOCS = sorted((REPO / "docs").glob("*.md"))

FENCE = re.compile(r"^```.*?^```[ \t]*$", re.S | re.M)
INLINE_CODE = re.compile(r"`[^`\n]*`")
LINK = re.compile(r"!?\[[^\]\n]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def prose(text: str) -> str:
    """The text without fenced code blocks and inline code (a link there is not a link)."""
    return INLINE_CODE.sub("", FENCE.sub("", text))


def sections(text: str, level: int = 2) -> dict[str, str]:
    """Heading text -> the section's body (code blocks included), for the headings of one level;
    a line starting with # inside a code block is no heading."""
    out, name, body, in_code = {}, None, [], False
    for line in text.splitlines():
        if line.startswith("```"):
            in_code = not in_code
        m = None if in_code else re.match(r"(#+)\s+(.*)", line)
        if m and len(m.group(1)) == level:
            if name is not None:
                out[name] = "\n".join(body)
            name, body = m.group(2).strip(), []
        elif name is not None:
            body.append(line)
    if name is not None:
        out[name] = "\n".join(body)
    return out


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def anchors(md: Path) -> set[str]:
    """The anchors of a Markdown file's headings (a repeated heading gets -1, -2, ...)."""
    seen: dict[str, int] = {}
    out = set()
    for line in FENCE.sub("", md.read_text()).splitlines():
        m = re.match(r"#{1,6}\s+(.*)", line)
        if not m:
            continue
        s = slug(m.group(1))
        out.add(s if s not in seen else f"{s}-{seen[s]}")
        seen[s] = seen.get(s, 0) + 1
    return out


def relative_links(md: Path) -> list[str]:
    return [t for t in LINK.findall(prose(md.read_text()))
            if not re.match(r"[a-z][a-z0-9+.-]*:", t, re.I)]       # http:, https:, mailto: ...


def broken_links(md: Path) -> list[str]:
    bad = []
    for target in relative_links(md):
        path, _, anchor = target.partition("#")
        dest = (md.parent / path).resolve() if path else md
        where = f"{md.relative_to(REPO)}: link '{target}'"
        if not dest.exists():
            bad.append(f"{where}: no file {dest.relative_to(REPO) if dest.is_relative_to(REPO) else dest}")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            bad.append(f"{where}: {dest.name} has no heading with the anchor '#{anchor}'")
    return bad


# ---------------------------------------------------------------------------------------------
# the checker itself, on made-up files (so that a test that passes has looked)
def test_the_link_checker_finds_missing_files_and_anchors(tmp_path, monkeypatch):
    monkeypatch.setattr(f"{__name__}.REPO", tmp_path)
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "a.md").write_text("# Title\n\n## The search, step by step\n\n## Time: caps, the budget\n")
    md = tmp_path / "README.md"
    md.write_text("# Read me\n[ok](docs/a.md) [ok](docs/a.md#the-search-step-by-step) [ok](docs/a.md#time-caps-the-budget)\n"
                  "![img](docs/a.md) [web](https://example.org/x) `[code](nowhere.md)`\n"
                  "```\n[block](nowhere.md)\n```\n"
                  "[gone](docs/b.md) [bad anchor](docs/a.md#no-such-heading) [self](#read-me)\n")
    bad = broken_links(md)
    assert len(bad) == 2, bad
    assert "no file docs/b.md" in bad[0] and "no heading with the anchor '#no-such-heading'" in bad[1]


def test_slug_follows_github():
    assert slug("Time: caps, the budget, long records") == "time-caps-the-budget-long-records"
    assert slug("validate's tolerance") == "validates-tolerance"
    assert slug("The `tether fit` command") == "the-tether-fit-command"
    assert (slug("Discovery on the held-out draw, before any change (seed 2026, 2026-11-26)")
            == "discovery-on-the-held-out-draw-before-any-change-seed-2026-2026-11-26")


# ---------------------------------------------------------------------------------------------
# the repository's documents
def test_readme_is_under_its_limit():
    n = len(README.read_text())
    assert n < README_LIMIT, (f"README.md is {n} characters, the limit is {README_LIMIT} (issue 25): move "
                              "details into docs/ and link them")


@pytest.mark.parametrize("md", [README] + DOCS, ids=lambda p: p.relative_to(REPO).as_posix())
def test_relative_links_resolve(md):
    bad = broken_links(md)
    assert not bad, "\n".join(bad)


def test_readme_tells_discovery_briefly_and_links_its_document():
    disc = [body for name, body in sections(README.read_text()).items() if name.startswith("Discovery")]
    assert len(disc) == 1, "README.md: no (or more than one) section whose heading starts with 'Discovery'"
    lines = [ln for ln in disc[0].splitlines() if ln.strip()]
    assert len(lines) <= 14, f"README.md tells discovery in {len(lines)} lines (about ten: docs/discovery.md holds the rest)"
    assert "(docs/discovery.md)" in disc[0]


def test_readme_maps_every_document():
    linked = {Path(t.partition("#")[0]).as_posix() for t in relative_links(README)}
    missing = [d.relative_to(REPO).as_posix() for d in DOCS if d.relative_to(REPO).as_posix() not in linked]
    assert not missing, f"README.md links no line to {missing}: add one line per document to its map of docs/"


def the_two_commands() -> list[list[str]]:
    body = sections(README.read_text()).get("The two commands")
    assert body is not None, "README.md: no section 'The two commands'"
    block = re.search(r"```sh\n(.*?)```", body, re.S)
    assert block, "README.md, 'The two commands': no ```sh block"
    return [shlex.split(ln, comments=True) for ln in block.group(1).splitlines() if shlex.split(ln, comments=True)]


def test_the_two_commands_are_the_scripts_ci_runs():
    cmds = the_two_commands()
    assert cmds == [["bash", "scripts/demo.sh"], ["bash", "scripts/test.sh"]], cmds
    for _, script in cmds:
        assert (REPO / script).is_file(), script
    # CI runs the README's test command, and nothing else
    ci = [shlex.split(ln, comments=True) for ln in (REPO / ".ci" / "run").read_text().splitlines()]
    runs = [c[1:] if c[0] == "exec" else c for c in ci if c and c[0] in ("exec", "bash")]
    assert runs == [cmds[1]], f".ci/run runs {runs}, the README says CI runs {cmds[1]}"
    # the demo is the main job (tether demo, the report the README names) after the setup test.sh runs too
    demo = (REPO / "scripts" / "demo.sh").read_text()
    test = (REPO / "scripts" / "test.sh").read_text()
    assert "bash scripts/setup.sh" in demo and "bash scripts/setup.sh" in test
    assert re.search(r"tether demo --report reports/demo\b", demo)
    assert "reports/demo/index.html" in README.read_text()


def tour() -> list[list[str]]:
    body = sections(README.read_text()).get("The command line")
    assert body is not None, "README.md: no section 'The command line'"
    block = re.search(r"```sh\n(.*?)```", body, re.S)
    assert block, "README.md, 'The command line': no ```sh block"
    return [shlex.split(ln, comments=True) for ln in block.group(1).splitlines() if ln.strip()]


def test_the_command_line_tour_has_one_example_of_each_command():
    from tether.cli import COMMANDS

    cmds = tour()
    assert all(c[0] == "tether" for c in cmds), cmds
    assert [c[1] for c in cmds] == [m.NAME for m in COMMANDS]


def trace_exists(arg: str) -> bool:
    p = REPO / arg
    stem = p.with_suffix("") if p.suffix in (".csv", ".json") else p
    return (stem.with_suffix(".json").is_file()
            and (stem.with_suffix(".csv").is_file() or stem.with_name(stem.name + ".csv.gz").is_file()))


def test_each_tour_example_parses_and_names_existing_traces():
    from tether.cli import build_parser

    bad = []
    for argv in tour():
        try:
            args = build_parser().parse_args(argv[1:])
        except SystemExit as e:                   # argparse's one-line error, already on stderr
            bad.append(f"does not parse (exit {e.code}): {' '.join(argv)}")
            continue
        given = getattr(args, "traces", None) or [getattr(args, "trace", None)]
        bad += [f"no trace {t}: {' '.join(argv)}" for t in given if t is not None and not trace_exists(t)]
    assert not bad, "README.md's command-line tour:\n" + "\n".join(bad)
