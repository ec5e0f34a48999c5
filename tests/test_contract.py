"""The experiment contract: one registry, the same roles in the same files, no import cycles,
scenario defaults in one place (the same from the CLI and Python), the demo's rule."""

import ast
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from launcher import wb
from typer.testing import CliRunner

import workbench
from workbench import cli
from workbench.config import settings
from workbench.core import experiment as contract
from workbench.core.registry import REGISTRY, get
from workbench.experiments.sea.config import SeaConfig
from workbench.experiments.terrain.config import TerrainConfig

PACKAGE = Path(workbench.__file__).parent
ROLES = ("config", "scenario", "estimate", "estimators", "run", "metrics", "evaluate", "record", "report",
         "experiment")


def test_every_experiment_has_the_same_files_for_the_same_roles():
    for name in REGISTRY:
        files = {p.stem for p in (PACKAGE / "experiments" / name).glob("*.py")}
        assert set(ROLES) <= files, (name, set(ROLES) - files)
        # shaped alike: the estimators and the file readers in sub-packages of their own
        assert all((PACKAGE / "experiments" / name / sub / "__init__.py").exists() for sub in ("algorithms", "readers"))
        exp = get(name)
        assert exp.name == name and set(exp.default_estimators) <= set(exp.estimators)
        assert all(e.experiment == name and e.ref == e.name and e.builtin for e in exp.estimators.values())


def _modules(package: Path = PACKAGE) -> dict[str, Path]:
    out = {}
    for path in package.rglob("*.py"):
        rel = path.relative_to(package.parent).with_suffix("")
        out[".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)] = path
    return out


def _imports(path: Path, modules: dict[str, Path], root: str = "workbench") -> set[str]:
    """Modules of the package a module imports, anywhere in it (a lazy import inside a function
    is a dependency too): ``from pkg import mod`` is an import of ``pkg.mod`` alone, ``from pkg
    import name`` (not a module) of ``pkg``; and a string that names one of its modules
    (``"pkg.mod"`` or ``"pkg.mod:function"``, what a string import would load) is an edge too."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith(root):
            subs = {f"{node.module}.{a.name}" for a in node.names} & set(modules)
            out |= subs | ({node.module} if len(subs) < len(node.names) else set())
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith(root))
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            named = re.fullmatch(rf"({re.escape(root)}(?:\.\w+)+)(?::[\w.]+)?", node.value.strip())
            # a package's bare name is not an import (an entry-point group is named so)
            if named and named.group(1) in modules and (":" in node.value
                                                         or modules[named.group(1)].stem != "__init__"):
                out.add(named.group(1))
    return out


def import_graph(package: Path = PACKAGE) -> dict[str, set[str]]:
    modules = _modules(package)
    root = package.name
    return {m: {i for i in _imports(p, modules, root) if i in modules and i != m} for m, p in modules.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A path of modules that reaches its first again, or None."""
    state: dict[str, int] = {}

    def visit(m, stack):
        state[m] = 1
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                return [*stack, m, n]
            if n not in state:
                found = visit(n, [*stack, m])
                if found:
                    return found
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state:
            found = visit(m, [])
            if found:
                return found
    return None


def test_no_import_cycles():
    """No module of the package reaches itself through its imports, lazy and string ones included."""
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_a_cycle_made_on_purpose_is_found(tmp_path):
    """The test above fails on a cycle through a lazy import, and on one through a string import
    (``"pkg.mod:function"`` handed to a loader), which Python's own imports would not show."""
    pkg = tmp_path / "demo_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from demo_pkg import b\n")
    (pkg / "b.py").write_text("def f():\n    from demo_pkg.c import g\n    return g\n")
    (pkg / "c.py").write_text("def g():\n    return 1\n")
    assert find_cycle(import_graph(pkg)) is None
    (pkg / "c.py").write_text("def g():\n    from demo_pkg.a import b\n    return b\n")
    assert find_cycle(import_graph(pkg)) == ["demo_pkg.a", "demo_pkg.b", "demo_pkg.c", "demo_pkg.a"]
    (pkg / "c.py").write_text("import importlib\n\ndef g():\n    return importlib.import_module('demo_pkg.a')\n")
    assert find_cycle(import_graph(pkg)) == ["demo_pkg.a", "demo_pkg.b", "demo_pkg.c", "demo_pkg.a"]
    (pkg / "c.py").write_text("RUN = 'demo_pkg.a:main'\n")
    assert find_cycle(import_graph(pkg)) == ["demo_pkg.a", "demo_pkg.b", "demo_pkg.c", "demo_pkg.a"]


def test_no_string_imports_of_its_own_modules():
    """Nothing of the workbench loads its own modules by name: ``importlib`` loads only what a user
    names (:mod:`workbench.loading`: plugins, entry points, files)."""
    users = {m for m, p in _modules().items()
             if "import_module(" in p.read_text() or "spec_from_file_location(" in p.read_text()}
    assert users == {"workbench.loading"}, users


BELOW = {"workbench.estimation": ("workbench.estimation", "workbench.errors"),
         "workbench.recording": ("workbench.recording", "workbench.errors", "workbench.paths", "workbench.version"),
         "workbench.io": ("workbench.io", "workbench.errors", "=workbench.recording.stream"),
         "workbench.config": ("workbench.config", "workbench.errors", "=workbench.loading"),
         "workbench.core.estimator": ("workbench.core.estimator", "workbench.loading", "workbench.errors",
                                      "=workbench.core.timeout"),
         "workbench.core.timeout": ("=workbench.core.timeout", "workbench.errors"),
         "workbench.metrics.base": ("workbench.metrics.base", "workbench.loading", "workbench.errors",
                                    "workbench.estimation")}
"""Layers and what each may import: the math, the drawing primitives, the estimator side of the
contract, the files and the settings (``=`` that module alone)."""


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
    """No module over 450 lines, none exempt; the command line at most 250 and nothing
    experiment-specific."""
    sizes = {str(p.relative_to(PACKAGE)): len(p.read_text().splitlines()) for p in PACKAGE.rglob("*.py")}
    over = {f: n for f, n in sizes.items() if n > 450}
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


OLD_PATHS = {"workbench.experiments.contract": "workbench.core.experiment",
             "workbench.experiments.estimator": "workbench.core.estimator",
             "workbench.experiments.metric": "workbench.metrics.base",
             "workbench.experiments.settings": "workbench.config.settings",
             "workbench.experiments.figures": "workbench.metrics.statistics",
             "workbench.experiments.textfile": "workbench.io.text",
             "workbench.montecarlo": "workbench.core.montecarlo",
             "workbench.tuning.selftune": "workbench.core.selftune"}


@pytest.mark.parametrize("old,new", sorted(OLD_PATHS.items()))
def test_an_old_module_path_warns_and_is_the_new_module(old, new):
    code = ("import warnings, importlib\nwarnings.simplefilter('always')\n"
            "with warnings.catch_warnings(record=True) as w:\n"
            f"    old = importlib.import_module({old!r})\n"
            f"assert old is importlib.import_module({new!r}), old\n"
            f"assert [str(x.message) for x in w if x.category.__name__ == 'MovedWarning'] == "
            f"[{old!r} + ' has moved to ' + {new!r} + '; the old path goes in the next release'], "
            "[str(x.message) for x in w]\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-1500:]


def test_a_plugin_written_against_the_old_paths_still_runs(tmp_path):
    """An estimator file of the last release, importing from workbench.experiments.*: it runs, and
    the user is told where the names went (a FutureWarning, shown without any filter set)."""
    (tmp_path / "old_plugin.py").write_text(
        "from workbench.experiments.estimator import estimator\n"
        "from workbench.experiments.sea.algorithms import geometric\n\n\n"
        "@estimator(description='the geometric fix, from an old plugin', causal=True)\n"
        "def old_fix(data, cfg):\n"
        "    return geometric.estimate(data)\n")
    done = subprocess.run([sys.executable, "-m", "workbench", "sea", "--runs", "1", "--duration", "20",
                           "--estimators", "geometric,old_plugin.py:old_fix", "--out", "old.rrd"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-1500:]
    assert "old_fix" in done.stdout
    assert "warning: workbench.experiments.estimator has moved to workbench.core.estimator" in done.stderr


def test_a_declaration_is_checked_with_one_clear_error():
    from workbench.core import parts
    from workbench.core.experiment import Experiment
    from workbench.errors import WorkbenchError

    sea = get("sea")
    with pytest.raises(WorkbenchError, match=r"declares no part called make_dat; its parts are make_data, check"):
        parts.declare("mine", make_dat=sea.parts.make_data, check=sea.parts.check, estimators={}, metrics=())
    with pytest.raises(WorkbenchError, match=r"'mine' does not declare its metrics \(a required part\)"):
        parts.declare("mine", make_data=sea.parts.make_data, check=sea.parts.check, estimators={})

    class Mine(Experiment):
        name = "mine"
        config_type = SeaConfig
        scenarios = sea.scenarios

        def declare(self):
            return parts.declare(self.name, make_data=sea.parts.make_data, check="estimate.check",
                                 estimators=sea.estimators, metrics=sea.parts.metrics)

    with pytest.raises(WorkbenchError, match="its part check is str, not a function"):
        Mine().check_declaration()
    assert all(get(n).check_declaration() is get(n) for n in REGISTRY)


def test_the_registry_names_of_the_last_release_warn():
    code = ("import warnings\nwarnings.simplefilter('error')\nimport workbench.experiments as e\n"
            "try:\n    e.get('sea')\nexcept Warning as w:\n    print(type(w).__name__, w)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.stdout.strip() == ("MovedWarning workbench.experiments.get has moved to workbench.core.registry; "
                                   "the old path goes in the next release"), done.stdout + done.stderr
