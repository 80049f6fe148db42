"""The README a user reads: short, no development history, tables that are the committed
data, links that lead somewhere, and a quickstart that runs."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

import fetch_env

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _tables_script():
    path = ROOT / "scripts" / "make_readme_tables.py"
    spec = importlib.util.spec_from_file_location("make_readme_tables", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_readme_is_at_most_12_kb() -> None:
    assert README.stat().st_size <= 12288


def test_readme_tells_no_development_history() -> None:
    """No dated history (the word "session" followed by a number): that is CHANGELOG.md's."""
    hits = [line for line in README.read_text().splitlines()
            if HISTORY.search(line)]
    assert hits == []


HISTORY = re.compile(r"sessions? ?[0-9]", re.IGNORECASE)


def test_no_development_history_anywhere() -> None:
    """The same over every text the project ships: docs, code, tests, benchmarks, scripts,
    notebooks (each hit named with its file and line)."""
    root = README.parent
    hits = []
    for folder in ("docs", "fetch_env", "estimators", "agents", "tests", "benchmarks",
                   "scripts", "notebooks"):
        for path in sorted((root / folder).rglob("*")):
            if path.suffix not in (".md", ".py", ".ipynb", ".yml", ".sh", ".txt"):
                continue
            for n, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
                if HISTORY.search(line):
                    hits.append(f"{path.relative_to(root)}:{n}")
    assert hits == []


@pytest.mark.parametrize("name", ["physics", "headroom", "speed", "soak"])
def test_readme_results_table_is_the_committed_json(name: str) -> None:
    """Each generated table is what scripts/make_readme_tables.py makes from the committed
    JSON now (rerun the script after a new benchmark run; never edit a table by hand)."""
    tables = _tables_script()
    assert tables.block(README.read_text(), name) == tables.render(name).strip()


def test_the_readme_headroom_table_shows_the_newest_id_of_each_family() -> None:
    tables = _tables_script()
    ids = ["FoodFetch-Block-v0", "FoodFetch-Block-v1", "FoodFetch-Row-v1", "FoodFetch-Row-v2",
           "FoodFetch-TwoRows-v2", "FoodFetch-TwoRows-v3", "FoodFetch-Diced-v1"]
    assert tables.latest_ids(ids) == ["FoodFetch-Block-v1", "FoodFetch-Row-v2",
                                      "FoodFetch-TwoRows-v3", "FoodFetch-Diced-v1"]
    assert tables.latest_ids(["FoodFetch-TwoRows-v1", "FoodFetch-TwoRows-v2"]) == [
        "FoodFetch-TwoRows-v2"]  # the newest the run measured


def _relative_links(text: str) -> list[str]:
    targets = re.findall(r"\]\(([^)\s]+)\)", text)
    targets += re.findall(r"^\[[^\]]+\]:\s*(\S+)", text, re.MULTILINE)
    return [t for t in targets if not re.match(r"[a-z][a-z0-9+.-]*:", t) and
            not t.startswith("#")]


def test_every_relative_link_in_the_readme_leads_to_a_file() -> None:
    links = _relative_links(README.read_text())
    assert links, "the README links into the documentation"
    missing = [t for t in links if not (ROOT / t.split("#", 1)[0]).exists()]
    assert missing == []


def test_every_registered_env_id_is_in_the_readme_with_its_page() -> None:
    text = README.read_text()
    for env_id in fetch_env.ENV_IDS:
        assert re.search(rf"\[[^]]+\]\(docs/environments/{env_id}\.md\)", text), env_id


@pytest.mark.slow
def test_the_readme_quickstart_runs(tmp_path: Path) -> None:
    """Every Python block of the README runs as written (10-30 s)."""
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), re.DOTALL)
    assert len(blocks) >= 2
    for i, code in enumerate(blocks):
        script = tmp_path / f"block{i}.py"
        script.write_text(code)
        done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                              text=True, timeout=600)
        assert done.returncode == 0, f"README Python block {i}:\n{done.stderr[-2000:]}"


def test_agents_page_theta_sweep_table_is_the_committed_json() -> None:
    """docs/agents.md's constant-against-per-scene table is what the sweep JSON files say."""
    path = ROOT / "benchmarks" / "theta_sweep.py"
    spec = importlib.util.spec_from_file_location("theta_sweep", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    table = module.table_markdown()
    assert table.count("\n") >= 5  # header, rule and a row per swept id
    page = (ROOT / "docs" / "agents.md").read_text()
    assert f"{module.MARK[0]}\n{table}\n{module.MARK[1]}" in page
