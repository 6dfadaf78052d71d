"""The documentation holds together: every relative link resolves, and README.md stays an entrance.

Checked files: README.md, every docs/*.md, and every README.md in the repository (build trees, virtual
environments and hidden folders are skipped). A link is a markdown inline link or image, `[text](target)` or
`![alt](target)`, or a reference definition `[label]: target`, outside code blocks and code spans. http(s):// and
mailto: targets are not checked (no network). A relative target must exist inside the repository, as a file or a
directory; a `#anchor` into a markdown file (or the same file) must name one of its headings, by GitHub's slug rule.

Standard library only; it does not import dynid.
"""

from __future__ import annotations

import os
import re
import unicodedata
from pathlib import Path
from urllib.parse import unquote

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
MAX_README_LINES = 200
SKIP_DIRS = {"build", "build-asan", "out", "node_modules", "__pycache__"}


def _is_generated_tree(path: Path) -> bool:
    """A CMake build tree or a Python virtual environment, whatever it is called."""
    return (path / "CMakeCache.txt").exists() or (path / "pyvenv.cfg").exists()


def documentation_files() -> list[Path]:
    files = {README} if README.exists() else set()
    files.update((ROOT / "docs").glob("*.md"))
    for directory, subdirs, names in os.walk(ROOT):
        here = Path(directory)
        subdirs[:] = sorted(d for d in subdirs if not d.startswith(".") and d not in SKIP_DIRS
                            and not d.endswith(".egg-info") and not _is_generated_tree(here / d))
        if "README.md" in names:
            files.add(here / "README.md")
    return sorted(files)


# ---- markdown, as far as links and headings need it ----------------------------------------------------------

FENCE = re.compile(r"^ {0,3}(`{3,}|~{3,})")
CODE_SPAN = re.compile(r"(`+)(?:.|\n)*?(?<!`)\1(?!`)")
INLINE_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*(<[^>]*>|[^()\s]*(?:\([^()\s]*\)[^()\s]*)*)(?:\s+(?:\"[^\"]*\"|'[^']*'|\([^()]*\)))?\s*\)")
REFERENCE_DEFINITION = re.compile(r"^ {0,3}\[[^\]]+\]:\s*(<[^>]*>|\S+)", re.MULTILINE)
ATX_HEADING = re.compile(r"^ {0,3}(#{1,6})(?:[ \t]+(.*?))?(?:[ \t]+#+)?[ \t]*$")
SETEXT_UNDERLINE = re.compile(r"^ {0,3}(=+|-+)[ \t]*$")
HTML_ANCHOR = re.compile(r"<a\s+(?:[^>]*?\s)?(?:name|id)\s*=\s*[\"']([^\"']+)[\"']", re.IGNORECASE)


def prose_lines(text: str) -> list[str]:
    """The lines of `text` with fenced code blocks blanked (line numbers kept)."""
    out, fence = [], None
    for line in text.splitlines():
        m = FENCE.match(line)
        if fence is None and m:
            fence = m.group(1)
            out.append("")
        elif fence is not None:
            if m and m.group(1)[0] == fence[0] and len(m.group(1)) >= len(fence) and not line.strip()[len(m.group(1)):].strip():
                fence = None
            out.append("")
        else:
            out.append(line)
    return out


def strip_code_spans(text: str) -> str:
    return CODE_SPAN.sub(lambda m: " " * len(m.group(0)), text)


def heading_text_to_plain(text: str) -> str:
    text = re.sub(r"!?\[((?:[^\[\]]|\[[^\[\]]*\])*)\]\([^)]*\)", r"\1", text)  # links and images: their text
    text = re.sub(r"<[^>]+>", "", text)  # inline HTML
    return text.replace("`", "").replace("*", "")


def github_slug(text: str) -> str:
    """GitHub's heading anchor: lower case; keep letters, marks, digits, '_', '-' and spaces; spaces become '-'."""
    plain = heading_text_to_plain(text).strip().lower()
    kept = "".join(c for c in plain if c in " -_" or unicodedata.category(c)[0] in "LMN")
    return kept.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """Every anchor a markdown file offers: its headings' slugs (duplicates numbered -1, -2, …) and HTML anchors."""
    lines = prose_lines(path.read_text(encoding="utf-8"))
    seen: dict[str, int] = {}
    out: set[str] = set()

    def add(heading: str) -> None:
        slug = github_slug(heading)
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")

    for i, line in enumerate(lines):
        m = ATX_HEADING.match(line)
        if m:
            add(m.group(2) or "")
        elif (i + 1 < len(lines) and line.strip() and not line.lstrip().startswith(("|", ">", "-", "*", "+"))
              and SETEXT_UNDERLINE.match(lines[i + 1]) and not ATX_HEADING.match(line)):
            add(line.strip())
        out.update(a for a in HTML_ANCHOR.findall(line))
    return out


def links(path: Path) -> list[tuple[int, str]]:
    """(line number, target) of every link in a markdown file, outside code."""
    found = []
    lines = prose_lines(path.read_text(encoding="utf-8"))
    text = strip_code_spans("\n".join(lines))
    for pattern in (INLINE_LINK, REFERENCE_DEFINITION):
        for m in pattern.finditer(text):
            target = m.group(1).strip()
            if target.startswith("<") and target.endswith(">"):
                target = target[1:-1]
            found.append((text.count("\n", 0, m.start()) + 1, target))
    return sorted(found)


def broken_links(path: Path, root: Path = ROOT) -> list[str]:
    problems = []
    root, path = root.resolve(), path.resolve()
    name = path.relative_to(root).as_posix()
    for line, target in links(path):
        if re.match(r"^(https?:|mailto:)", target, re.IGNORECASE):
            continue
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.IGNORECASE):
            problems.append(f"{name}:{line}: '{target}': not a relative link (only http(s) and "
                            "mailto are allowed besides)")
            continue
        where, _, anchor = target.partition("#")
        where = unquote(where)
        if where.startswith("/"):
            problems.append(f"{name}:{line}: '{target}': absolute path; use a relative one")
            continue
        resolved = (path.parent / where).resolve() if where else path
        try:
            resolved.relative_to(root)
        except ValueError:
            problems.append(f"{name}:{line}: '{target}' leaves the repository: a clone cannot "
                            "follow it")
            continue
        if not resolved.exists():
            problems.append(f"{name}:{line}: '{target}': {resolved.relative_to(root)} does not exist")
            continue
        if anchor and resolved.is_file() and resolved.suffix.lower() in (".md", ".markdown"):
            if unquote(anchor).lower() not in anchors(resolved):
                problems.append(f"{name}:{line}: '{target}': no heading '#{anchor}' in "
                                f"{resolved.relative_to(root)}")
    return problems


# ---- the tests -----------------------------------------------------------------------------------------------

DOCS = documentation_files()


def test_the_documentation_is_found():
    names = {p.relative_to(ROOT).as_posix() for p in DOCS}
    assert "README.md" in names
    assert any(n.startswith("docs/") for n in names), "no docs/*.md found"


@pytest.mark.parametrize("path", DOCS, ids=[p.relative_to(ROOT).as_posix() for p in DOCS])
def test_relative_links_resolve(path: Path):
    problems = broken_links(path)
    assert not problems, f"{len(problems)} broken link(s):\n" + "\n".join(problems)


def test_readme_is_an_entrance():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= MAX_README_LINES, f"README.md has {len(lines)} lines; at most {MAX_README_LINES}: move detail to docs/"


def test_readme_starts_with_the_two_commands():
    text = README.read_text(encoding="utf-8")
    m = re.search(r"^ {0,3}(`{3,}|~{3,})[^\n]*\n(.*?)^ {0,3}\1", text, re.MULTILINE | re.DOTALL)
    assert m, "README.md has no fenced code block"
    block = m.group(2)
    for command in ("scripts/main", "scripts/test"):
        assert re.search(rf"^\s*(?:\$\s*)?{re.escape(command)}\b", block, re.MULTILINE), \
            f"README.md's first code block does not start a line with {command}"


def test_docs_do_not_point_outside_the_repository_for_the_design():
    """The design brief outside the repository cannot be followed from a clone: docs/design.md is the reference."""
    for path in [README, *sorted((ROOT / "docs").glob("*.md"))]:
        assert "shared/DESIGN.md" not in path.read_text(encoding="utf-8"), f"{path.relative_to(ROOT)} cites shared/DESIGN.md"


# ---- the checker itself --------------------------------------------------------------------------------------


@pytest.mark.parametrize("heading, slug", [
    ("1. What users get", "1-what-users-get"),
    ("Model gaps (`dynid gaps`)", "model-gaps-dynid-gaps"),
    ("Bodies and the F/T split", "bodies-and-the-ft-split"),
    ("rt_monitor configuration", "rt_monitor-configuration"),
    ("Watching it: dynid spy, lcm-spy, LCM logs", "watching-it-dynid-spy-lcm-spy-lcm-logs"),
    ("Supply tracking (a dynid addition)", "supply-tracking-a-dynid-addition"),
    ("The [core](x.md) *fast*", "the-core-fast"),
])
def test_github_slug(heading: str, slug: str):
    assert github_slug(heading) == slug


def test_checker_finds_broken_links(tmp_path: Path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "a.md").write_text("# A\n\n## Same\n\n## Same\n\nSetext\n------\n", encoding="utf-8")
    doc = tmp_path / "README.md"
    doc.write_text(
        "# Top\n\n"
        "[ok](docs/a.md) [ok](docs/a.md#same-1) [ok](docs/a.md#setext) [ok](docs) [ok](#top) "
        "[web](https://example.org/x) [mail](mailto:x@example.org)\n"
        "`[not a link](nowhere.md)`\n\n```\n[not a link](nowhere.md)\n```\n"
        "[missing](docs/b.md) [bad anchor](docs/a.md#nope) [outside](../elsewhere.md) [self](#nothing)\n"
        "[ref]: docs/missing-too.md\n",
        encoding="utf-8")
    problems = broken_links(doc, root=tmp_path)
    assert len(problems) == 5, problems
    for bad in ("docs/b.md", "#nope", "../elsewhere.md", "#nothing", "missing-too.md"):
        assert any(bad in p for p in problems), (bad, problems)
