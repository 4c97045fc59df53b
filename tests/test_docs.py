"""The documentation the code relies on is in the repository and current."""

from __future__ import annotations

import re
import runpy
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TABLE = runpy.run_path(str(REPO / "scripts" / "architecture_table.py"))


def test_the_architecture_table_is_generated_from_the_code():
    readme = (REPO / "docs" / "architecture.md").read_text()
    assert TABLE["table"]() in readme, "run: python scripts/architecture_table.py --write"


def test_every_module_under_src_is_named_in_the_architecture_table():
    readme = (REPO / "docs" / "architecture.md").read_text()
    table = readme[readme.index(TABLE["BEGIN"]) : readme.index(TABLE["END"])]
    rows = {line.split("|")[1].strip(" `"): line for line in table.splitlines()[3:]}
    src = REPO / "src"
    for path in src.rglob("*.py"):
        package = ".".join(("simgap", *path.parent.relative_to(src).parts))
        if path.stem != "__init__":
            assert f"`{path.stem}`" in rows[package].split("|")[3], f"{path} not in the table"


def test_every_section_the_code_cites_is_in_docs_conventions():
    conventions = (REPO / "docs" / "conventions.md").read_text()
    sections = set(re.findall(r"^## (\d+)\. ", conventions, re.M))
    cited = {
        m
        for folder in ("src", "tests", "mitsuba_scenes")
        for path in (REPO / folder).rglob("*")
        if path.suffix in (".py", ".yaml")
        for m in re.findall(r"docs/conventions\.md §(\d+)", path.read_text())
    }
    assert cited and cited <= sections
    text = "".join(p.read_text() for p in (REPO / "src").rglob("*.py"))
    assert "DESIGN" not in text  # a file outside the repository


DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
README_CHECK = runpy.run_path(str(REPO / "scripts" / "readme_check.py"))


def _command_lines() -> list[tuple[Path, str]]:
    """Each line of the ``bash`` blocks of the README and docs/, comments and joins removed."""
    lines = []
    for page in DOCS:
        for block in README_CHECK["blocks"](page.read_text()):
            for line in block.replace("\\\n", " ").splitlines():
                line = line.split(" #")[0].strip()
                if line and not line.startswith("#"):
                    lines.append((page, line))
    return lines


def test_every_link_of_the_readme_and_docs_names_a_file_of_the_repository():
    for page in DOCS:
        for target in re.findall(r"\]\(([^)#]+)\)", page.read_text()):
            if not target.startswith("http"):
                assert (page.parent / target).exists(), f"{page.name}: link to missing {target}"


def test_every_script_the_readme_and_docs_run_exists():
    for page, line in _command_lines():
        for script in re.findall(r"(?:bash|python) ((?:scripts|benchmarks)/\S+)", line):
            assert (REPO / script).is_file(), f"{page.name}: {line}"
        for path in re.findall(r"\b((?:experiments|docs/examples)/\S+\.yaml)\b", line):
            assert (REPO / path).is_file(), f"{page.name}: {line}"


def test_every_simgap_command_of_the_readme_and_docs_names_a_command_and_its_options():
    import typer

    from simgap.cli import app

    root = typer.main.get_command(app)
    seen = 0
    for page, line in _command_lines():
        words = line.split()
        if not words or not words[0].endswith("simgap") or words[0].startswith("-"):
            continue
        rest = [w for w in words[1:] if w != "--debug"]
        if not rest or rest[0].startswith("-"):
            continue
        command = root.get_command(None, rest[0])  # type: ignore[arg-type]
        assert command is not None, f"{page.name}: no command {rest[0]!r} in {line!r}"
        names = {n for p in command.params for n in (*p.opts, *p.secondary_opts)}
        for word in rest[1:]:
            if word.startswith("-"):
                assert word.split("=")[0] in names, f"{page.name}: {word} unknown in {line!r}"
        seen += 1
    assert seen >= 15  # README and docs/ show at least this many simgap calls today


def test_every_repository_path_the_experiments_and_scenes_name_exists():
    for folder in ("experiments", "mitsuba_scenes", "docs/examples"):
        for path in (REPO / folder).glob("*.yaml"):
            text = path.read_text()
            pattern = r"\b((?:src|mitsuba_scenes|experiments|docs)/[\w/.-]+\.\w+)"
            for named in re.findall(pattern, text):
                assert (REPO / named).exists(), f"{path.name} names missing {named}"
