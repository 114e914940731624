"""The README's relative links and pictures point at files that exist (the site moved nothing)."""

from __future__ import annotations

import re

from .markdown_blocks import ROOT

LINK = re.compile(r'\]\((?P<target>[^)\s#]+)(#[^)\s]*)?\)')


def test_readme_links_resolve():
    targets = [match['target'] for match in LINK.finditer((ROOT / 'README.md').read_text())]
    local = [target for target in targets if not target.startswith(('http://', 'https://', 'mailto:'))]
    assert len(local) >= 10
    missing = [target for target in local if not (ROOT / target).exists()]
    assert not missing, f'README.md links to missing files: {missing}'
