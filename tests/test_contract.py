"""The experiment contract: one registry, the same roles in the same files, no import cycles,
scenario defaults in one place (the same from the CLI and Python), the demo's rule."""

import ast
import json
import re
from pathlib import Path

import pytest
from launcher import wb
from typer.testing import CliRunner

import workbench
from workbench import cli
from workbench.experiments import REGISTRY, contract, get, settings
from workbench.experiments.sea.config import SeaConfig
from workbench.experiments.terrain.config import TerrainConfig

PACKAGE = Path(workbench.__file__).parent
ROLES = ("config", "scenario", "estimate", "estimators", "run", "metrics", "evaluate", "record", "report",
         "experiment")


def test_every_experiment_has_the_same_files_for_the_same_roles():
    for name in REGISTRY:
        files = {p.stem for p in (PACKAGE / "experiments" / name).glob("*.py")}
        assert set(ROLES) <= files, (name, set(ROLES) - files)
        exp = get(name)
        assert exp.name == name and set(exp.default_estimators) <= set(exp.estimators)
        assert all(e.experiment == name and e.ref == e.name and e.builtin for e in exp.estimators.values())


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        out[".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)] = path
    return out


def _imports(path: Path, modules: dict[str, Path]) -> set[str]:
    """Modules of the package a module imports, anywhere in it (a lazy import inside a function
    is a dependency too): ``from pkg import mod`` is an import of ``pkg.mod`` alone, ``from pkg
    import name`` (not a module) of ``pkg``."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("workbench"):
            subs = {f"{node.module}.{a.name}" for a in node.names} & set(modules)
            out |= subs | ({node.module} if len(subs) < len(node.names) else set())
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("workbench"))
    return out


def import_graph() -> dict[str, set[str]]:
    modules = _modules()
    return {m: {i for i in _imports(p, modules) if i in modules and i != m} for m, p in modules.items()}


def test_no_import_cycles():
    """No module of the package reaches itself through its imports, lazy ones included."""
    graph = import_graph()
    state: dict[str, int] = {}

    def visit(m, stack):
        state[m] = 1
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                raise AssertionError("import cycle: " + " -> ".join([*stack, m, n]))
            if n not in state:
                visit(n, [*stack, m])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [])


BELOW = {"workbench.estimation": ("workbench.estimation", "workbench.errors"),
         "workbench.recording": ("workbench.recording", "workbench.errors", "workbench.paths", "workbench.version"),
         "workbench.experiments.estimator": ("workbench.experiments.estimator", "workbench.loading", "workbench.errors",
                                             "=workbench.experiments", "=workbench.experiments.deadline"),
         "workbench.experiments.deadline": ("=workbench.experiments.deadline", "workbench.errors"),
         "workbench.experiments.metric": ("workbench.experiments.metric", "workbench.loading", "workbench.errors",
                                          "workbench.estimation")}
"""Layers and what each may import: the math, the drawing primitives, the estimator side of the
contract (the registry's lookup aside, ``=`` that module alone: a worker finds an estimator
again by its experiment)."""


def test_no_upward_imports():
    """The math and the drawing primitives import nothing above them; the estimator side of the
    contract nothing of the experiment side; the tools that run experiments are above the API
    and nothing below them imports them."""
    graph = import_graph()
    for layer, allowed in BELOW.items():
        for m, deps in graph.items():
            if m == layer or m.startswith(layer + "."):
                up = {d for d in deps if not any(d == a.lstrip("=") or (a[0] != "=" and d.startswith(a + "."))
                                                 for a in allowed)}
                assert not up, f"{m} imports {sorted(up)}, above its layer"
    users = {m for m, deps in graph.items() if any(d.startswith("workbench.tools") for d in deps)}
    assert users <= {"workbench", "workbench.cli"} | {m for m in graph if m.startswith("workbench.tools")}, users


def test_file_sizes():
    """No module over 450 lines but one algorithm each (the omni factor graph, the terrain search and
    bundle adjustment, the sea detector); the command line at most 250 and nothing experiment-specific."""
    one_algorithm = {"experiments/omni/graph.py", "experiments/terrain/search.py", "experiments/terrain/ba.py"}
    sizes = {str(p.relative_to(PACKAGE)): len(p.read_text().splitlines()) for p in PACKAGE.rglob("*.py")}
    over = {f: n for f, n in sizes.items() if n > 450 and f not in one_algorithm}
    assert not over, over
    assert sizes["cli.py"] <= 250
    cli_text = (PACKAGE / "cli.py").read_text()
    named = re.findall(r"\b(omni|sea|terrain|measure|mrclam|ngi|ais)\b", cli_text)
    assert not named, f"cli.py names an experiment or its command: {named}"


def test_scenario_defaults_live_in_the_config():
    """The ais mast and run length, the ngi frame size: the same from Python, the API and the CLI."""
    ais = SeaConfig(scenario="ais")
    assert (ais.height, ais.duration, ais.sigma_acc) == (20.0, 180.0, 0.3)
    assert SeaConfig(scenario="ais", height=3.0).height == 3.0        # given beats the scenario
    assert SeaConfig().height == 3.0 and TerrainConfig(scenario="ngi").size == "160x288"
    assert workbench.configure("sea", "ais", duration=60.0).height == 20.0
    with pytest.raises(workbench.errors.WorkbenchError, match="unknown scenario 'nowhere'"):
        SeaConfig(scenario="nowhere")
    with pytest.raises(workbench.errors.WorkbenchError, match="sea has no setting bogus"):
        workbench.configure("sea", bogus=1)
    assert settings.default_text(SeaConfig, get("sea").scenarios, "height") == "[3; ais 20]"
    r = CliRunner().invoke(cli.app, ["sea", "--help"], terminal_width=200, env={"COLUMNS": "200"})
    assert "Camera height h, m. [3; ais 20]" in r.output, r.output


def test_the_api_and_the_cli_give_the_same_numbers(tmp_path):
    m = tmp_path / "m.json"
    r = wb("sea", "--runs", "3", "--seed", "3", "--duration", "10", "--out", str(tmp_path / "a.rrd"),
           "--metrics", str(m))
    assert r.returncode == 0, r.stderr
    cli_stats = json.loads(m.read_text())
    api_stats = workbench.run("sea", runs=3, seed=3, duration=10.0).metrics
    for name, e in cli_stats["estimators"].items():
        assert api_stats["estimators"][name]["rmse_x"] == e["rmse_x"] == e["rmse"]["x"], name


@pytest.fixture
def demo_in(tmp_path, monkeypatch):
    """The demo command with its steps replaced, writing into a scratch folder."""
    monkeypatch.setattr(cli, "RECORDINGS", tmp_path / "rec")
    monkeypatch.setenv("WORKBENCH_DATA", str(tmp_path / "no-data-here"))

    def run(steps: dict):
        for name in REGISTRY:
            monkeypatch.setattr(get(name), "demo", steps.get(name, ()))
        return CliRunner().invoke(cli.app, ["demo", "--runs", "2"])

    return run


def test_the_demo_skips_only_absent_data(demo_in):
    r = demo_in({"sea": (contract.Demo("s-paper", "paper", {"duration": 5.0}), contract.Demo("s-ais", "ais")),
                 "terrain": (contract.Demo("t-ngi", "ngi", {"mode": "ii-only"}),)})
    assert r.exit_code == 0, r.output
    assert "s-ais            skipped: data file not found" in r.output and "t-ngi            skipped" in r.output
    assert "s-paper          -> " in r.output


def test_the_demo_fails_on_anything_else(demo_in):
    r = demo_in({"sea": (contract.Demo("s-bad", "paper", {"lam": 5.0}),)})
    assert r.exit_code == 2 and "--lam must be in (0, 1]" in r.output
