"""The documentation site: one page per registered environment id, generated pages current,
every page in the navigation (``mkdocs build --strict`` in ``.ci/run`` checks the links)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

yaml = pytest.importorskip("yaml")

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _make_env_pages():
    spec = importlib.util.spec_from_file_location(
        "make_env_pages", ROOT / "scripts" / "make_env_pages.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _nav_pages(node) -> list[str]:
    """Every page path listed in mkdocs.yml's nav, however nested."""
    if isinstance(node, str):
        return [node]
    if isinstance(node, list):
        return [page for item in node for page in _nav_pages(item)]
    if isinstance(node, dict):
        return [page for value in node.values() for page in _nav_pages(value)]
    return []


def _config() -> dict:
    # mkdocs.yml may use tags such as !!python/name; only nav is read here
    class Loader(yaml.SafeLoader):
        pass

    Loader.add_multi_constructor("", lambda loader, suffix, node: None)
    return yaml.load((ROOT / "mkdocs.yml").read_text(), Loader=Loader)


def test_every_registered_env_id_has_its_page() -> None:
    import fetch_env

    for env_id in fetch_env.ENV_IDS:
        page = DOCS / "environments" / f"{env_id}.md"
        assert page.is_file(), f"{page} missing: run python scripts/make_env_pages.py"
        assert page.read_text().startswith(f"# {env_id}\n")


def test_the_committed_env_pages_are_what_the_script_writes_now() -> None:
    for path, text in _make_env_pages().pages().items():
        assert path.is_file(), f"{path} missing: run python scripts/make_env_pages.py"
        assert path.read_text() == text, (
            f"{path.relative_to(ROOT)} differs from the env class docstring: "
            "run python scripts/make_env_pages.py"
        )


def test_every_page_under_docs_is_in_the_navigation() -> None:
    config = _config()
    nav = set(_nav_pages(config["nav"]))
    excluded = ("data/", "figures/")  # tables beside the figures, not site pages
    pages = {
        str(path.relative_to(DOCS))
        for path in DOCS.rglob("*.md")
        if not str(path.relative_to(DOCS)).startswith(excluded)
    }
    assert pages - nav == set(), f"pages not in mkdocs.yml's nav: {sorted(pages - nav)}"
    assert nav - pages == set(), f"nav entries without a page: {sorted(nav - pages)}"
