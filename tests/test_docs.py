"""The documentation the code relies on is in the repository and current."""

from __future__ import annotations

import re
import runpy
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TABLE = runpy.run_path(str(REPO / "scripts" / "architecture_table.py"))


def test_the_readme_architecture_table_is_generated_from_the_code():
    readme = (REPO / "README.md").read_text()
    assert TABLE["table"]() in readme, "run: python scripts/architecture_table.py --write"


def test_every_module_under_src_is_named_in_the_readme_architecture_table():
    readme = (REPO / "README.md").read_text()
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
