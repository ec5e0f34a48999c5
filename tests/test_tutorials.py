"""The tutorials' sh blocks run in order in a scratch folder, so the tutorials stay true.

Blocks fenced ``sh real-data`` need the real data (``WORKBENCH_DATA`` or ``../shared/data``)
and are skipped, with the reason, where it is absent.
"""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from workbench.paths import data_root

TUTORIALS = sorted((Path(__file__).resolve().parents[1] / "tutorials").glob("*.md"))


@pytest.mark.parametrize("path", TUTORIALS, ids=lambda p: p.stem)
def test_tutorial_runs(path, tmp_path):
    blocks = re.findall(r"```sh( real-data)?\n(.*?)```", path.read_text(), flags=re.S)
    assert blocks, f"{path.name} has no sh blocks"
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    (tmp_path / "tut").mkdir()
    skipped = []
    outputs = []
    for real, block in blocks:
        if real and not data_root().is_dir():
            skipped.append(block.strip())
            continue
        for line in block.strip().splitlines():
            r = subprocess.run(line, shell=True, cwd=tmp_path, env=env, capture_output=True,
                               text=True, timeout=900)
            assert r.returncode == 0, f"{line}\n{r.stderr[-2000:]}"
            outputs += re.findall(r"--out (\S+)", line)
    for out in outputs:
        assert (tmp_path / out).stat().st_size > 0, out
    if skipped:
        pytest.skip(f"ran all but {len(skipped)} real-data block(s): no data at {data_root()}")
