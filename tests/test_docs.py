"""The docs: the README is a front door whose example runs, and the site (README, docs/, the
tutorials, the API pages from the docstrings) builds with mkdocs --strict: a broken link, a
missing page or a docstring the API pages cannot render fails here."""

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def test_readme_is_a_front_door():
    text = README.read_text()
    assert len(text.splitlines()) <= 170 and len(text.encode()) <= 12_000, (len(text.splitlines()), len(text))
    assert text.splitlines()[3:5] == ["make demo    # creates .venv, installs, runs every experiment; recordings in "
                                      "recordings/",
                                      "make test    # creates .venv, installs, runs ruff, the docs' build and the "
                                      "whole test suite"]
    for target in re.findall(r"\]\(([^)#]+)\)", text):
        if not target.startswith("http"):
            assert (ROOT / target).exists(), f"README links to {target}, which is not there"


def test_readme_example_runs(tmp_path):
    """The ten-line estimator of the README, as written: it beats the paper's geometric fix it averages."""
    code = re.search(r"```python\n(.*?)```", README.read_text(), re.S).group(1)
    code += "\nassert res.metrics['estimators']['averaged_fix']['position_rmse'] < " \
            "res.metrics['estimators']['geometric']['position_rmse']\n"
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (tmp_path / "mine.rrd").stat().st_size > 0


def test_the_site_builds_strictly(tmp_path):
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    home = (tmp_path / "site" / "index.html").read_text()
    assert "Your own estimator, in ten lines" in home
    api = (tmp_path / "site" / "api" / "experiments" / "index.html").read_text()
    assert "check_declaration" in api and "Parts" in api   # the API pages come from the docstrings
    tutorial = (tmp_path / "site" / "tutorials" / "new-experiment" / "index.html").read_text()
    assert tutorial.count("<code") > 20   # the tutorials' fences read as code


def test_a_broken_link_fails_the_build(tmp_path):
    """The check can fail: a page linking to a page that is not there stops the strict build."""
    site = tmp_path / "docs"
    site.mkdir()
    (site / "index.md").write_text("# home\n\n[gone](nowhere.md)\n")
    (tmp_path / "mkdocs.yml").write_text("site_name: t\nstrict: true\n")
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode != 0 and "nowhere.md" in done.stderr  # (mkdocs -q would hide it: not used)


def test_the_public_api_documents_its_parameters():
    """The functions a user calls first carry Args and Returns sections, which the API pages
    render as tables (mkdocstrings, Google style)."""
    import inspect

    import workbench
    from workbench.core import parts, registry

    for fn in (workbench.run, workbench.configure, registry.get, parts.declare, workbench.Experiment.configure,
               workbench.Experiment.select, workbench.Experiment.estimate):
        doc = inspect.getdoc(fn)
        assert "Args:" in doc and "Returns:" in doc, fn.__qualname__
        named = set(re.findall(r"^    (\*{0,2}\w+):", doc.split("Args:")[1].split("Returns:")[0], re.M))
        params = {("**" if p.kind is p.VAR_KEYWORD else "") + p.name
                  for p in inspect.signature(fn).parameters.values() if p.name != "self"}
        assert named == params, (fn.__qualname__, params ^ named)


def test_the_paths_the_docs_name_are_there():
    """A file of the repository named in the README or a docs page (``workbench/...py``,
    ``tests/...``, ``benchmarks/...``, ``docs/...``) exists: a move that forgets a page fails here."""
    missing: dict[str, set] = {}
    path = re.compile(r"((?:workbench|tests|benchmarks|docs)/[\w/.-]+\.(?:py|md|json|toml))")
    for page in [README, *(ROOT / "docs").rglob("*.md")]:
        for named in path.findall(page.read_text()):
            if not (ROOT / named).exists():
                missing.setdefault(page.name, set()).add(named)
    assert not missing, missing
