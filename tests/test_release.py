"""What a release needs beside the code: ``food-fetch --version`` from the package metadata,
a LICENSE matching ``pyproject.toml``, a CITATION.cff that parses and cites the study, and no
reference in the code or the docs to a repository file that does not exist."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from importlib.metadata import version
from pathlib import Path

import pytest

yaml = pytest.importorskip("yaml")

ROOT = Path(__file__).resolve().parents[1]


def test_version_prints_the_installed_version() -> None:
    proc = subprocess.run([sys.executable, "-m", "agents.cli", "--version"], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"food-fetch {version('food-fetch')}"
    assert proc.stderr == ""


def test_the_installed_version_is_this_tree_s() -> None:
    """The metadata ``--version`` reads is this checkout's (an editable install), so the
    printed version is pyproject.toml's."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert version("food-fetch") == project["version"]


def test_license_is_the_apache_2_text_pyproject_names() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["license"] == "Apache-2.0"
    text = (ROOT / "LICENSE").read_text()
    assert "Apache License" in text and "Version 2.0, January 2004" in text
    # the full text, not a notice: all nine sections and the appendix
    for heading in ("1. Definitions.", "4. Redistribution.", "9. Accepting Warranty or "
                    "Additional Liability.", "APPENDIX: How to apply the Apache License"):
        assert heading in text, heading


def _check_reference(ref: dict, where: str) -> None:
    for key in ("type", "title", "authors"):
        assert key in ref, f"{where}: {key} missing"
    assert ref["authors"] and all(("name" in a) or ("family-names" in a)
                                  for a in ref["authors"]), f"{where}: bad authors"


def test_citation_cff_parses_and_cites_the_project_and_the_study() -> None:
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    # the keys CFF 1.2.0 requires, and the authors' form it allows (a person or an entity)
    for key in ("cff-version", "message", "title", "authors"):
        assert key in cff, key
    assert cff["cff-version"] == "1.2.0"
    assert cff["authors"] and all(("name" in a) or ("family-names" in a)
                                  for a in cff["authors"])
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert cff["version"] == project["version"] and cff["license"] == project["license"]
    study = cff["preferred-citation"]
    _check_reference(study, "preferred-citation")
    assert study["type"] == "article"
    assert "Viscoelasticity and friction of solid foods" in " ".join(study["title"].split())
    assert study["journal"] == "International Journal of Food Properties"
    assert (study["year"], study["start"], study["end"]) == (2022, 2301, 2319)
    for i, ref in enumerate(cff.get("references", [])):
        _check_reference(ref, f"references[{i}]")
    # dates are strings in CFF (YAML would otherwise read a bare date as a date object)
    assert isinstance(study["date-published"], str)


# Paths from the repository root that code and docs mention (``docs/agents.md``,
# ``agents/hyperparams/ppo.yml``), top-level files named in capitals (``CHANGELOG.md``,
# ``LICENSE``), and relative links in markdown pages.  A path given as a command's output
# (``--out docs/data/x.json``, also as the option's default) is written by that command, so
# need not exist beforehand.
FOLDERS = ("docs", "benchmarks", "scripts", "tests", "agents", "fetch_env", "estimators",
           "notebooks")
EXTENSIONS = ("md", "py", "yml", "yaml", "json", "jsonl", "csv", "png", "ipynb", "xml",
              "txt", "npz", "sh", "cff")
_FOLDER, _EXT = "|".join(FOLDERS), "|".join(EXTENSIONS)
REPO_PATH = re.compile(rf"(?<![\w/.\-~$])((?:{_FOLDER})/[\w./\-]*\.(?:{_EXT}))(?![\w/])")
TOP_FILE = re.compile(r"(?<![\w/.\-])([A-Z][A-Z_]*\.(?:md|cff)|LICENSE)(?![\w.])")
MD_LINK = re.compile(r"\]\(([^)\s]+)\)")
SCANNED = (".py", ".md", ".ipynb", ".yml", ".toml", ".cff", ".sh")
OUTPUT_OPTION = re.compile(r"--(out|json|csv|plots|video|episodes-log)\b")


def _tracked() -> list[Path]:
    try:
        out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                             timeout=60, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout: the scan reads git's list of files")
    return [ROOT / f for f in out.splitlines() if Path(f).suffix in SCANNED]


def _missing_references(path: Path) -> list[str]:
    text = path.read_text(errors="replace")
    found = []
    for m in REPO_PATH.finditer(text):
        line = text[text.rfind("\n", 0, m.start()) + 1:m.start()]
        if not OUTPUT_OPTION.search(line):
            found.append(m.group(1))
    found += [m.group(1) for m in TOP_FILE.finditer(text)]
    missing = [ref for ref in found if not (ROOT / ref).exists()]
    if path.suffix == ".md":
        for m in MD_LINK.finditer(text):
            target = m.group(1).split("#")[0]
            if target and not re.match(r"^[a-z]+:", target) \
                    and not (path.parent / target).exists():
                missing.append(target)
    return missing


def test_the_scan_finds_a_missing_file(tmp_path: Path) -> None:
    """The scan itself can fail: a page naming files that are not there is caught."""
    # (the names are put together here, so that this file itself names no missing file)
    notes, nowhere, gone = "STUDY_NOTES" + ".md", "docs/" + "nowhere.md", "scripts/" + "gone.py"
    page = tmp_path / "page.md"
    page.write_text(f"See {notes}, {nowhere}, `{gone}` and [the guide](missing.md); "
                    "docs/agents.md is real; run --out docs/data/new.json.\n")
    assert sorted(_missing_references(page)) == sorted([notes, nowhere, "missing.md", gone])


def test_code_and_docs_refer_only_to_files_that_exist() -> None:
    missing = [f"{path.relative_to(ROOT)}: {ref}" for path in _tracked()
               for ref in _missing_references(path)]
    assert missing == []
