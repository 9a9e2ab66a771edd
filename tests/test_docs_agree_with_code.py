"""The README and the manual under docs/ agree with the code: the command synopsis in
docs/command_line.md names only commands and options the `physcap` command has (as its
`--help` shows them) and every top-level command; every relative link points to a file."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import typer.main

from physcap_drake.cli import app

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
COMMAND_LINE = DOCS / "command_line.md"

#: Pages other branches are adding at the same time; until they are merged a link to them
#: may dangle. Remove each name once its page is on main.
PENDING_PAGES: frozenset[str] = frozenset()  # pages linked before they are written

LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
OPTION = re.compile(r"(?<![\w-])(--?[a-zA-Z][\w-]*)")


def command_tree() -> dict[tuple[str, ...], set[str]]:
    """Every command path of `physcap` (groups included) with the options its help lists."""
    tree: dict[tuple[str, ...], set[str]] = {}

    def walk(command, path: tuple[str, ...]) -> None:
        tree[path] = {name for param in command.params if param.param_type_name == "option"
                      for name in (*param.opts, *param.secondary_opts)}
        if hasattr(command, "list_commands"):
            for name in command.list_commands(None):
                walk(command.get_command(None, name), (*path, name))

    walk(typer.main.get_command(app), ())
    return tree


def synopsis_lines(text: str) -> list[str]:
    """The lines of the first ```bash block after the page's `## Synopsis` heading."""
    section = text[text.index("## Synopsis\n"):]
    start = section.index("```bash\n") + len("```bash\n")
    return section[start:section.index("```", start)].strip().splitlines()


def parse_synopsis(lines: list[str]) -> tuple[dict[tuple[str, ...], set[str]], set[str]]:
    """(command path -> options written for it, options of the shared MODEL OPTIONS line).
    `physcap arm status|estop` names several subcommands with the same options."""
    commands: dict[tuple[str, ...], set[str]] = {}
    shared: set[str] = set()
    for line in lines:
        if line.strip().startswith("MODEL OPTIONS:"):
            shared |= set(OPTION.findall(line.split(":", 1)[1]))
            continue
        words = line.split()
        assert words[0] == "physcap", f"a synopsis line that is not a command: {line!r}"
        path_words = []
        for word in words[1:]:
            if word.startswith(("-", "[", "<")):
                break
            path_words.append(word)
        options = set(OPTION.findall(line))
        alternatives = path_words[-1].split("|") if path_words else [""]
        for last in alternatives:
            path = tuple(path_words[:-1]) + ((last,) if last else ())
            commands.setdefault(path, set()).update(options)
            if "[MODEL OPTIONS]" in line:
                commands[path].add("MODEL OPTIONS")
    return commands, shared


def test_every_command_and_option_in_the_synopsis_exists():
    tree = command_tree()
    written, shared = parse_synopsis(synopsis_lines(COMMAND_LINE.read_text()))
    assert written, "the synopsis is empty"
    for path, options in written.items():
        assert path in tree, f"docs/command_line.md names `physcap {' '.join(path)}`, " \
                             "which does not exist"
        if "MODEL OPTIONS" in options:
            options = (options - {"MODEL OPTIONS"}) | shared
        missing = options - tree[path] - {"-h", "--help"}
        assert not missing, f"`physcap {' '.join(path)}` has no option {sorted(missing)}"


def test_every_top_level_command_is_in_the_synopsis():
    tree = command_tree()
    written, _ = parse_synopsis(synopsis_lines(COMMAND_LINE.read_text()))
    top = {path[0] for path in tree if len(path) == 1}
    named = {path[0] for path in written if path}
    assert top - named == set(), "commands missing from docs/command_line.md's synopsis"


def test_the_synopsis_parser_sees_a_wrong_option_and_a_missing_command():
    tree = command_tree()
    written, _ = parse_synopsis(["physcap replay <F> [--html F] [--no-such-option]",
                                 "physcap arm status|estop [--scenario F]"])
    assert written[("replay",)] - tree[("replay",)] == {"--no-such-option"}
    assert written[("arm", "status")] == written[("arm", "estop")] == {"--scenario"}
    assert ("run",) not in written


def markdown_files() -> list[Path]:
    return [REPO / "README.md", *sorted(DOCS.rglob("*.md"))]


def relative_links(page: Path) -> list[str]:
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    return [target for target in LINK.findall(text)
            if not re.match(r"^[a-z][a-z0-9+.-]*:", target) and not target.startswith("#")]


@pytest.mark.parametrize("page", markdown_files(), ids=lambda p: str(p.relative_to(REPO)))
def test_every_relative_link_points_to_a_file(page):
    broken = []
    for target in relative_links(page):
        resolved = (page.parent / target.split("#", 1)[0]).resolve()
        name = resolved.relative_to(REPO).as_posix() if resolved.is_relative_to(REPO) else target
        if not resolved.exists() and name not in PENDING_PAGES:
            broken.append(target)
    assert broken == [], f"{page.relative_to(REPO)} links to files that do not exist"


def test_the_link_finder_sees_links_and_skips_urls_and_code(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("[a](docs/x.md#part) ![fig](y.png) [web](https://e.org) [here](#top)\n"
                    "```\n[not](a_link.md)\n```\n")
    assert relative_links(page) == ["docs/x.md#part", "y.png"]
