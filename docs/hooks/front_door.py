"""mkdocs hook: the README is the site's home page and CHANGELOG.md its changelog, from the one
source each (their links to ``docs/...`` read from inside the docs folder)."""

from __future__ import annotations

import re
from pathlib import Path

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[2]


def _inside_docs(text: str) -> str:
    text = re.sub(r"\]\(docs/", "](", text)
    return text.replace("](CHANGELOG.md)", "](changelog.md)")


def on_files(files: Files, config) -> Files:
    for name, uri in (("README.md", "index.md"), ("CHANGELOG.md", "changelog.md")):
        files.append(File.generated(config, uri, content=_inside_docs((ROOT / name).read_text())))
    return files


FENCE = re.compile(r"^(`{3,})(\w+)[ ]+(\S.*)$", re.M)


def on_page_markdown(markdown: str, page, config, files) -> str:
    """A fence's words after the language (the tutorials' ``python run`` and ``python
    file=landmark/config.py``, which the tests read) become a caption above a plain fence, which
    Markdown reads as code."""
    return FENCE.sub(lambda m: f"*{m.group(3)}*\n\n{m.group(1)}{m.group(2)}", markdown)
