"""The front door: a README of at most 300 lines whose quick start is the two commands, every
page it links to present, and no development log in the user documentation."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

pytestmark = pytest.mark.meta

REPO = Path(__file__).resolve().parents[1]
README = (REPO / 'README.md').read_text()


def test_readme_is_a_front_door() -> None:
    assert len(README.splitlines()) <= 300
    quick = README.split('## Quick start', 1)[1].split('```sh', 1)[1].split('```', 1)[0]
    assert [line.strip() for line in quick.strip().splitlines()] == ['make demo', 'make test']


def test_every_linked_page_and_picture_exists() -> None:
    pages = [REPO / 'README.md', *sorted((REPO / 'docs').glob('*.md'))]
    missing = []
    for page in pages:
        for target in re.findall(r'\]\(([^)#\s]+)\)', page.read_text()):
            if target.startswith(('http://', 'https://')):
                continue
            if not (page.parent / target).exists():
                missing.append(f'{page.relative_to(REPO)} -> {target}')
    assert not missing, missing


def test_user_documentation_has_no_history() -> None:
    log = re.compile(r'\bround \d\b|\bthis session\b|\bsession \d+\b', re.IGNORECASE)
    found = [
        f'{p.name}: {m.group(0)}'
        for p in [REPO / 'README.md', *(REPO / 'docs').glob('*.md')]
        for m in log.finditer(p.read_text())
    ]
    assert not found, found


def test_license_is_the_one_the_manifests_name() -> None:
    assert 'Apache License' in (REPO / 'LICENSE').read_text()
    for xml in (REPO / 'src').glob('*/package.xml'):
        assert '<license>Apache-2.0</license>' in xml.read_text(), xml
