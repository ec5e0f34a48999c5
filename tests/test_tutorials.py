"""The tutorials run in order in a scratch folder, so the tutorials stay true.

* ``sh`` blocks run line by line; ``sh real-data`` blocks need the real data
  (``WORKBENCH_DATA`` or ``../shared/data``) and are skipped, with the reason, where it is absent;
* ``python file=NAME`` (and ``toml file=NAME``) blocks are written to ``NAME`` (a file the reader
  saves; ``pkg/mod.py`` in a package folder);
* ``python run`` blocks run as a script (what the reader types into Python or a notebook).

A line that is a plain ``workbench ...`` command (no variable set before it, no shell syntax) runs
in this process (:func:`launcher.cli`, the command's own entry, in the reader's folder): a fresh
interpreter adds 2 s of imports a line, and the console script itself is run by ``make demo`` and
by the tests whose subject is the process. Every other line runs in the shell, as typed.
"""

import contextlib
import hashlib
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from launcher import cli

from workbench.paths import data_root

PACKAGE = Path(__file__).resolve().parents[1] / "workbench"


def _package_state() -> str:
    """A hash of every source file of the workbench: what a tutorial must leave as it is."""
    h = hashlib.sha1()
    for f in sorted(PACKAGE.rglob("*.py")):
        h.update(str(f.relative_to(PACKAGE)).encode() + f.read_bytes())
    return h.hexdigest()


TUTORIALS = sorted((Path(__file__).resolve().parents[1] / "docs" / "tutorials").glob("*.md"))
BLOCK = re.compile(r"```(sh real-data|sh|(?:python|toml) file=\S+|python run)\n(.*?)```", flags=re.S)
PLAIN = re.compile(r"workbench [^|&;<>$`\\*?~]*")
"""A ``workbench`` command with nothing for the shell to do but split its words (no glob, no ``~``)."""


def _line(line: str, folder: Path, env: dict) -> subprocess.CompletedProcess:
    """One ``sh`` line in ``folder``: a plain ``workbench`` command in this process, else the shell."""
    if not PLAIN.fullmatch(line):
        return subprocess.run(line, shell=True, cwd=folder, env=env, capture_output=True, text=True, timeout=900)
    with contextlib.chdir(folder):
        return cli(*shlex.split(line)[1:])


@pytest.mark.parametrize("path", TUTORIALS, ids=lambda p: p.stem)
def test_tutorial_runs(path, tmp_path):
    blocks = BLOCK.findall(path.read_text())
    assert any(kind.startswith("sh") for kind, _ in blocks), f"{path.name} has no sh blocks"
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    (tmp_path / "tut").mkdir()
    skipped = []
    outputs = []
    before = _package_state()
    written = []
    for kind, block in blocks:
        if kind == "sh real-data" and not data_root().is_dir():
            skipped.append(block.strip())
            continue
        if " file=" in kind:
            target = tmp_path / kind.split("=", 1)[1]
            target.parent.mkdir(parents=True, exist_ok=True)  # a file of a package the reader writes
            target.write_text(block)
            written.append(kind.split("=", 1)[1])
            continue
        if kind == "python run":
            r = subprocess.run([sys.executable, "-c", block], cwd=tmp_path, env=env, capture_output=True,
                               text=True, timeout=900)
            assert r.returncode == 0, f"{block}\n{r.stderr[-2000:]}"
            continue
        for line in block.strip().splitlines():
            r = _line(line, tmp_path, env)
            assert r.returncode == 0, f"{line}\n{r.stderr[-2000:]}"
            outputs += re.findall(r"--out (\S+)", line)
    for out in outputs:
        assert (tmp_path / out).stat().st_size > 0, out
    # an estimator, a metric or an experiment of your own is your files alone: none of the workbench's
    assert _package_state() == before, "the tutorial touched a file of the workbench"
    print(f"{path.stem}: files written by the reader: {', '.join(sorted(set(written))) or 'none'}")
    if skipped:
        pytest.skip(f"ran all but {len(skipped)} real-data block(s): no data at {data_root()}")
