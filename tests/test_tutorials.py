"""The tutorials' sh blocks run in order in a scratch folder, so the tutorials stay true."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

TUTORIALS = sorted((Path(__file__).resolve().parents[1] / "tutorials").glob("*.md"))


@pytest.mark.parametrize("path", TUTORIALS, ids=lambda p: p.stem)
def test_tutorial_runs(path, tmp_path):
    blocks = re.findall(r"```sh\n(.*?)```", path.read_text(), flags=re.S)
    assert blocks, f"{path.name} has no sh blocks"
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    (tmp_path / "tut").mkdir()
    for block in blocks:
        for line in block.strip().splitlines():
            r = subprocess.run(line, shell=True, cwd=tmp_path, env=env, capture_output=True,
                               text=True, timeout=600)
            assert r.returncode == 0, f"{line}\n{r.stderr[-2000:]}"
    assert (tmp_path / "tut" / "paper.rrd").stat().st_size > 0
