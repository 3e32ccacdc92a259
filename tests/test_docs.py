"""The documentation: the README short and its links whole, docs/ built as a site in strict mode
(a broken link or anchor between pages fails), the interfaces page as the sources give it."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from markdown.extensions.toc import slugify

REPO = Path(__file__).resolve().parents[1]
README_LINES = 250            # a README read in five minutes; the rest is in docs/
LINK = re.compile(r'\[[^\]]+\]\(([^)\s]+)\)')


def mkdocs(config: Path, site: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, '-m', 'mkdocs', 'build', '--strict', '-f',
                           str(config), '-d', str(site)], capture_output=True, text=True,
                          timeout=120)


def anchors(page: Path) -> set[str]:
    """The anchors of a Markdown page's headings, as mkdocs makes them."""
    return {slugify(re.sub(r'[`*]', '', m.group(1)).strip(), '-')
            for m in re.finditer(r'^#{1,6} (.+)$', page.read_text(encoding='utf-8'), re.M)}


def test_the_docs_build_without_a_broken_link_or_anchor(tmp_path: Path) -> None:
    result = mkdocs(REPO / 'mkdocs.yml', tmp_path / 'site')
    assert result.returncode == 0, result.stderr[-3000:]


def test_the_docs_build_fails_on_a_broken_anchor(tmp_path: Path) -> None:
    """The strict build is what catches a broken anchor: the same settings on a page with one."""
    docs = tmp_path / 'docs'
    docs.mkdir()
    (docs / 'index.md').write_text('# Home\n\nSee [the rest](other.md#no-such-part).\n')
    (docs / 'other.md').write_text('# Other\n\n## A part\n')
    config = (REPO / 'mkdocs.yml').read_text(encoding='utf-8')
    config = re.sub(r'(?ms)^nav:.*?(?=^\S)', '', config)
    (tmp_path / 'mkdocs.yml').write_text(config)
    result = mkdocs(tmp_path / 'mkdocs.yml', tmp_path / 'site')
    assert result.returncode != 0
    assert 'no-such-part' in result.stderr


def test_the_readme_is_short_and_its_links_lead_somewhere() -> None:
    readme = REPO / 'README.md'
    text = readme.read_text(encoding='utf-8')
    assert len(text.splitlines()) <= README_LINES
    links = [link for link in LINK.findall(text) if '://' not in link]
    assert links, 'the README links to the docs'
    for link in links:
        path, _, anchor = link.partition('#')
        target = REPO / path
        assert target.is_file(), f'README links to {link}: no such file'
        if anchor:
            assert anchor in anchors(target), f'README links to {link}: no such anchor'


def test_the_interfaces_page_is_what_the_sources_give() -> None:
    result = subprocess.run([sys.executable, str(REPO / 'scripts/interfaces_doc.py'),
                             '--check'], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
