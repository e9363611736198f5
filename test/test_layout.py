"""Package layout rules: the core runs without ROS; the shipped files agree with each other."""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml
from conftest import ROOT

# the source and the files, read: the same in every venv (setup.cfg's markers)
pytestmark = pytest.mark.static


def _fresh_python(code: str) -> str:
    """What ``code`` prints in a new interpreter on this checkout (sys.modules starts empty)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run(
        [sys.executable, '-c', code], capture_output=True, text=True, env=env, check=True, cwd=ROOT
    ).stdout


@pytest.mark.slow
def test_core_and_offline_tool_do_not_import_rclpy() -> None:
    # nor evo: it is GPLv3 and a test-only dependency
    code = (
        'import sys, handeye_ros.core.pipeline, handeye_ros.core.simulate, '
        'handeye_ros.app.offline, handeye_ros.formats, handeye_ros.evaluation.outputs, '
        'handeye_ros.evaluation.plots, handeye_ros.evaluation.html; '
        'print(sorted(m for m in sys.modules if m.split(".")[0] in ("rclpy", "rosbags", '
        '"evo")))'
    )
    assert _fresh_python(code).strip() == '[]'


#: One folder, one layer, lowest first: a module imports from its own layer or a lower one.
#: The application (app/: the command-line tools and what they share) sits between the
#: libraries and the ROS front end; the top level holds only the ``python -m`` entry points.
LAYERS = ('core', 'stream', 'formats', 'evaluation', 'app', '<top level>', 'ros')
#: The top level's modules: the package's lazy API and the two ``python -m`` entry points the
#: docs name (their code is in app/).
TOP_LEVEL = {'__init__.py', 'offline.py', 'evaluate.py'}


#: Inside core, lowest first: the foundations, the paper's math (the stages' own folders, which
#: never import the checks or the wiring), the checks around it, the stages as the pipeline
#: wires them (core/stages, which alone call the checks), and the recipe with its result.
CORE_FLOORS = (
    (
        'foundations',
        {'arrays', 'document', 'rig_document', 'errors', 'geometry', 'chunked', 'trajectory'},
    ),
    (
        'foundations',
        {'options', 'config'},
    ),
    ('foundations', {'association', 'world'}),
    ('math', {'time', 'linear', 'batch', 'eye_model', 'rig', 'simulate'}),
    ('checks', {'checks'}),
    ('stages', {'stages'}),
    ('recipe', {'pipeline', 'result', 'result_sections', 'rig_pipeline'}),
)


def _core_floor(module: str) -> int:
    part = module.split('.')[2]
    return next(k for k, (_, names) in enumerate(CORE_FLOORS) if part in names)


def _core_graph() -> dict[str, set[str]]:
    graph = {}
    for path in sorted((ROOT / 'handeye_ros' / 'core').rglob('*.py')):
        rel = path.relative_to(ROOT).with_suffix('')
        module = '.'.join(rel.parts[:-1] if rel.name == '__init__' else rel.parts)
        graph[module] = {
            t for t in _imports(path, module) if t.startswith('handeye_ros.core.') and t != module
        }
    return graph


def test_core_has_floors_and_no_cycle() -> None:
    """Inside core, nothing imports upward (CORE_FLOORS), and no import cycle, runtime or
    TYPE_CHECKING: the paper's math reads without the verdict or the wiring."""
    import graphlib

    graph = _core_graph()
    upward = [
        f'{m} ({CORE_FLOORS[_core_floor(m)][0]}) imports {t} ({CORE_FLOORS[_core_floor(t)][0]})'
        for m, targets in graph.items()
        if m.count('.') >= 2
        for t in targets
        if _core_floor(t) > _core_floor(m)
    ]
    assert not upward, '\n'.join(upward)
    graphlib.TopologicalSorter(graph).prepare()  # raises CycleError naming the cycle


def test_the_package_has_no_import_cycle() -> None:
    """No import cycle anywhere in the package, runtime or TYPE_CHECKING (a part the node
    holds reads it through a Protocol, ros/host.py, or explicit inputs)."""
    import graphlib

    graph = {}
    for path in sorted((ROOT / 'handeye_ros').rglob('*.py')):
        rel = path.relative_to(ROOT).with_suffix('')
        module = '.'.join(rel.parts[:-1] if rel.name == '__init__' else rel.parts)
        graph[module] = {t for t in _imports(path, module) if t != module}
    graphlib.TopologicalSorter(graph).prepare()  # raises CycleError naming the cycle


def test_the_top_level_holds_only_the_entry_points() -> None:
    assert {p.name for p in (ROOT / 'handeye_ros').glob('*.py')} == TOP_LEVEL


def _layer(module: str) -> int:
    parts = module.split('.')
    sub = parts[1] if len(parts) > 1 and parts[1] in LAYERS else '<top level>'
    return LAYERS.index(sub)


def _imports(path, module: str) -> set[str]:
    """Every handeye_ros module ``path`` imports, at module level or inside functions."""
    package = module if path.name == '__init__.py' else module.rsplit('.', 1)[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith('handeye_ros'))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split('.')
                base = base[: len(base) - node.level + 1]
                target = '.'.join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ''
            if not target.startswith('handeye_ros'):
                continue
            found.add(target)
            # ``from . import offline`` imports a module, not a name
            found.update(
                f'{target}.{a.name}'
                for a in node.names
                if (ROOT / Path(*f'{target}.{a.name}'.split('.'))).with_suffix('.py').is_file()
            )
    return found


def test_no_layer_imports_from_a_layer_above() -> None:
    upward = []
    for path in sorted((ROOT / 'handeye_ros').rglob('*.py')):
        rel = path.relative_to(ROOT).with_suffix('')
        module = '.'.join(rel.parts[:-1] if rel.name == '__init__' else rel.parts)
        for target in _imports(path, module):
            if _layer(target) > _layer(module):
                upward.append(
                    f'{module} ({LAYERS[_layer(module)]}) imports {target} '
                    f'({LAYERS[_layer(target)]})'
                )
    assert not upward, '\n'.join(upward)


@pytest.mark.slow
def test_public_api_is_small_documented_and_lazy() -> None:
    code = (
        'import sys, handeye_ros as h; before = "numpy" in sys.modules; '
        'names = [n for n in h.__all__ if getattr(h, n).__doc__]; '
        'print(before, names == h.__all__, "calibrate" in dir(h))'
    )
    assert _fresh_python(code).split() == ['False', 'True', 'True']


def test_package_xml_and_setup_agree() -> None:
    root = ET.parse(ROOT / 'package.xml').getroot()
    assert root.get('format') == '3'
    assert root.findtext('name') == 'handeye_ros'
    assert root.find('export/build_type').text == 'ament_python'
    setup = (ROOT / 'setup.py').read_text()
    assert "version='" + root.findtext('version') + "'" in setup
    assert (ROOT / 'resource' / 'handeye_ros').is_file()
    # ros2 run's names in lib/handeye_ros (ros2_run/); the PATH's: test_node_start_stop
    commands = ast.literal_eval(
        next(
            node.value
            for node in ast.parse(setup).body
            if isinstance(node, ast.Assign) and ast.unparse(node.targets[0]) == 'COMMANDS'
        )
    )
    assert sorted(p.name for p in (ROOT / 'ros2_run').iterdir()) == sorted(commands)
    for name, target in commands.items():
        script = ROOT / 'ros2_run' / name
        module = target.split(':')[0]
        assert os.access(script, os.X_OK), script
        assert f'from {module} import main' in script.read_text(), script


#: What each system key of package.xml is imported as (the package's own imports decide them).
PYTHON_KEYS = {
    'python3-numpy': 'numpy',
    'python3-scipy': 'scipy',
    'python3-yaml': 'yaml',
    'python3-rosbags-pip': 'rosbags',
    'python3-tqdm': 'tqdm',
    'python3-matplotlib': 'matplotlib',
}
#: Imported, deliberately not declared (package.xml says why for each).
UNDECLARED = {'mocap4r2_msgs', 'mocap_msgs', 'dask', 'distributed', 'rviz2'}


def _package_keys() -> dict[str, set[str]]:
    """package.xml's keys by tag (exec_depend, test_depend, ...)."""
    keys: dict[str, set[str]] = {}
    for el in ET.parse(ROOT / 'package.xml').getroot():
        if el.tag.endswith('depend'):
            keys.setdefault(el.tag, set()).add(el.text.strip())
    return keys


def test_package_xml_declares_what_the_package_imports_and_nothing_else() -> None:
    """The run-time keys are the third-party modules the package and its launch file import."""
    imported = set()
    for path in [*(ROOT / 'handeye_ros').rglob('*.py'), *(ROOT / 'launch').glob('*.py')]:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                imported.update(a.name.split('.')[0] for a in node.names)
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                imported.add(node.module.split('.')[0])
        # message packages are imported by name (ros/types.py, stream/convert.py)
        imported.update(re.findall(r"'([a-z0-9_]+_(?:msgs|srvs))[./']", path.read_text()))
    imported -= set(sys.stdlib_module_names) | {'handeye_ros'}
    exec_keys = _package_keys()['exec_depend']
    declared = {PYTHON_KEYS.get(k, k) for k in exec_keys} - {'ros2launch'}
    assert imported - UNDECLARED == declared, (
        f'imported, not declared: {sorted(imported - UNDECLARED - declared)}; '
        f'declared, not imported: {sorted(declared - imported)}'
    )
    assert not UNDECLARED & exec_keys


def _pins(name: str) -> dict[str, str]:
    """``package: version`` of a requirements file (every line pinned with ==)."""
    lines = [ln.split('#')[0].strip() for ln in (ROOT / name).read_text().splitlines()]
    pins = [ln for ln in lines if ln]
    assert all(re.fullmatch(r'[\w\-\[\]]+==[\w.]+', ln) for ln in pins), pins
    return {re.sub(r'\[.*\]', '', ln.split('==')[0]).lower(): ln.split('==')[1] for ln in pins}


def test_every_pin_lives_in_requirements_txt() -> None:
    """requirements.txt pins today's set; requirements-jazzy.txt the Jazzy platform's versions
    of some of them (installed in their place by scripts/setup --jazzy); setup.py holds no pin,
    and its lower bounds are the platform's versions."""
    setup = (ROOT / 'setup.py').read_text()
    assert not re.search(r"'[\w\-\[\]]+\s*(==|<=|~=)", setup), (
        'versions belong in requirements.txt'
    )
    today, jazzy = _pins('requirements.txt'), _pins('requirements-jazzy.txt')
    assert set(jazzy) <= set(today), set(jazzy) - set(today)
    bounds = dict(re.findall(r"'([\w\-]+)>=([\w.]+)'", setup))
    assert bounds, 'setup.py states the lower bounds'
    for name, low in bounds.items():
        assert low == jazzy.get(name, today[name]), (name, low)
    assert "python_requires='>=3.11'" in setup  # enum.StrEnum


def _bench_results():
    import importlib.util

    spec = importlib.util.spec_from_file_location('bench_results', ROOT / 'bench' / 'results.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_results_md_figures_come_from_registered_benchmarks() -> None:
    """Every generated block of bench/RESULTS.md and bench/results/*.md names an output that a
    benchmark of bench/results.py writes, and a refill replaces a block's body and nothing
    else."""
    import fnmatch

    res = _bench_results()
    names = [n for doc in res.DOCUMENTS for n in res.blocks(doc.read_text())]
    assert names, 'bench/results/ has no generated block'
    patterns = [o for _, _, outs, _ in res.BENCHMARKS.values() for o in outs]
    for name in names:
        assert any(fnmatch.fnmatch(name, p) for p in patterns), name
    for script, _, _, _ in res.BENCHMARKS.values():
        assert (ROOT / 'bench' / f'{script}.py').is_file(), script
    doc = 'a\n<!-- bench: x -->\n```text\nold\n```\n<!-- /bench -->\nb\n'
    new, changed, missing = res.refill(doc, {'x': 'new 1\nnew 2\n'})
    assert new == 'a\n<!-- bench: x -->\n```text\nnew 1\nnew 2\n```\n<!-- /bench -->\nb\n'
    assert (changed, missing) == (['x'], [])
    assert res.refill(new, {'x': 'new 1\nnew 2'})[1] == []  # unchanged: not reported
    assert res.refill(doc, {})[2] == ['x']


def test_the_tests_mirror_the_package() -> None:
    """Every folder of tests is a folder of the package (test/app: its top-level modules), but
    for the tests' data (message definitions, node scripts, golden records)."""
    for folder in sorted(p for p in (ROOT / 'test').rglob('*') if p.is_dir()):
        rel = folder.relative_to(ROOT / 'test')
        if rel.parts[0] in ('app', 'interfaces', 'ros_scripts', 'golden', '__pycache__') or (
            '__pycache__' in rel.parts
        ):
            continue
        assert (ROOT / 'handeye_ros' / rel).is_dir(), f'test/{rel} mirrors no package folder'


def test_the_launch_file_and_rviz_config_match_the_node() -> None:
    """launch/calibrator.launch.py starts executables the package installs, and the RViz
    config shows the node's latched paths in the eye's default world frame. Where launch is
    importable (a ROS 2 install), the description is also built."""
    from handeye_ros.ros.outputs import PATHS
    from handeye_ros.stream.config import FALLBACK_FRAMES

    launch = (ROOT / 'launch' / 'calibrator.launch.py').read_text()
    ast.parse(launch)
    setup = (ROOT / 'setup.py').read_text()
    for exe in re.findall(r"executable='([a-z_]+)'", launch):
        assert exe == 'rviz2' or (ROOT / 'ros2_run' / exe).is_file(), exe
    assert "glob('launch/*.launch.py')" in setup and "glob('config/*.rviz')" in setup
    rviz = yaml.safe_load((ROOT / 'config' / 'calibrator.rviz').read_text())
    manager = rviz['Visualization Manager']
    topics = {d['Topic']['Value'] for d in manager['Displays'] if 'Topic' in d}
    assert topics == {f'/calibrator/{name}' for name in PATHS.values()}
    assert manager['Global Options']['Fixed Frame'] == FALLBACK_FRAMES['eye_world']


def test_only_the_verdict_makes_reasons() -> None:
    """Every reason of a verdict is made by a rule of core/checks/verdict/: the stages hand it
    their findings and append what it returns (one place for every verdict rule)."""
    made = []
    for path in sorted((ROOT / 'handeye_ros').rglob('*.py')):
        if path.relative_to(ROOT).as_posix().startswith('handeye_ros/core/checks/verdict/'):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, 'id', None) == 'Reason':
                made.append(f'{path.relative_to(ROOT)}:{node.lineno}')
    assert not made, made


def test_every_module_is_named_where_its_folder_is_described() -> None:
    """Each package's docstring names each of its modules and subpackages (a newcomer reads the
    folder there)."""
    missing = []
    for init in sorted((ROOT / 'handeye_ros').rglob('__init__.py')):
        doc = ast.get_docstring(ast.parse(init.read_text())) or ''
        folder = init.parent
        names = [p.stem for p in folder.glob('*.py') if p.stem != '__init__']
        names += [p.name for p in folder.iterdir() if (p / '__init__.py').is_file()]
        missing += [f'{folder.relative_to(ROOT)}: {n}' for n in names if n not in doc]
    assert not missing, missing


#: Past this many lines a module is warned of (one meaning each, readable in one sitting).
MAX_MODULE_LINES = 800


def test_a_module_past_the_line_mark_is_warned_of() -> None:
    """Modules are cut by meaning, not to fit a cap: one past MAX_MODULE_LINES is a warning to
    look at, never a failure."""
    long = {
        str(p.relative_to(ROOT)): n
        for p in sorted((ROOT / 'handeye_ros').rglob('*.py'))
        if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES
    }
    if long:
        warnings.warn(f'modules past {MAX_MODULE_LINES} lines: {long}', stacklevel=1)


#: Most lines a function has (docstring included), and the ones allowed more, each with why.
MAX_FUNCTION_LINES = 60
LONG_FUNCTIONS = {
    # argparse builders: one add_argument per option, read as a table
    'app/offline_options.py:build_parser': 'argparse builder',
    'app/evaluate.py:build_parser': 'argparse builder',
    'ros/sim_options.py:parser': 'argparse builder',
    # dense Jacobian algebra, whose steps share too many arrays to part
    'core/linear/refits.py:degenerate_refit': 'one-axis algebra (the null space, what it fixes)',
}


def _package_functions() -> list[tuple[str, ast.FunctionDef | ast.AsyncFunctionDef]]:
    """Every function of the package, nested ones included, as ('folder/module.py:name', node)."""
    found = []
    for path in sorted((ROOT / 'handeye_ros').rglob('*.py')):
        rel = path.relative_to(ROOT / 'handeye_ros').as_posix()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                found.append((f'{rel}:{node.name}', node))
    return found


def _public_signatures() -> list[tuple[str, list[ast.expr]]]:
    """Every public function, method and dataclass field of the package (no leading underscore
    on it, its class or its module) with the annotations of its signature."""
    found: list[tuple[str, list[ast.expr]]] = []

    def walk(node: ast.AST, where: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef) and not child.name.startswith('_'):
                fields = [s for s in child.body if isinstance(s, ast.AnnAssign)]
                found.extend(
                    (f'{where}{child.name}.{ast.unparse(f.target)}', [f.annotation])
                    for f in fields
                )
                walk(child, f'{where}{child.name}.')
            elif isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef) and (
                not child.name.startswith('_') or child.name.startswith('__')
            ):
                a = child.args
                params = [*a.posonlyargs, *a.args, *a.kwonlyargs, a.vararg, a.kwarg]
                notes = [x.annotation for x in params if x is not None and x.annotation]
                found.append((f'{where}{child.name}', [*notes, *filter(None, [child.returns])]))

    for path in sorted((ROOT / 'handeye_ros').rglob('*.py')):
        rel = path.relative_to(ROOT / 'handeye_ros').as_posix()
        if not path.name.startswith('_') or path.name == '__init__.py':
            walk(ast.parse(path.read_text()), f'{rel}:')
    return found


def test_no_public_signature_says_any() -> None:
    """Issue 48's figure: the types a caller reads are real ones (the result documents are
    typed dictionaries, core/document.py); mypy, run by test_lint in both venvs, refuses a
    generic without its parameters and an unannotated function anywhere in the package."""
    said = [
        name
        for name, notes in _public_signatures()
        if any(isinstance(n, ast.Name) and n.id == 'Any' for a in notes for n in ast.walk(a))
        or any('Any' in ast.unparse(a) for a in notes if isinstance(a, ast.Constant))
    ]
    assert said == [], said


def test_no_function_is_over_60_lines_but_the_named_ones() -> None:
    """Functions with one job (issue 37's figure): none over MAX_FUNCTION_LINES, nested ones
    included, but LONG_FUNCTIONS; and each of those still is one."""
    long = {
        name
        for name, node in _package_functions()
        if node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES
    }
    assert long - set(LONG_FUNCTIONS) == set(), sorted(long - set(LONG_FUNCTIONS))
    assert set(LONG_FUNCTIONS) - long == set(), sorted(set(LONG_FUNCTIONS) - long)


#: Most required parameters (no default; self and cls not counted) a function takes.
MAX_REQUIRED_PARAMETERS = 6
#: The functions that take more, each with why its parameters do not form a record: the batch
#: stage's numerical kernels, whose arguments are the independent arrays of one computation.
MANY_PARAMETERS = {
    'core/batch/long_run.py:influence_two_step': (
        "each step's residuals and Jacobians and how the steps share their rows and parameters"
    ),
    'core/batch/residuals.py:__init__': (
        'BatchProblem: the whole problem of eq. 15 (streams, start, spline, drift and scale)'
    ),
}


def _required_parameters(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    a = node.args
    positional = a.posonlyargs + a.args
    n = len(positional) - len(a.defaults) + sum(d is None for d in a.kw_defaults)
    return n - (bool(positional) and positional[0].arg in ('self', 'cls'))


def test_few_functions_take_more_than_six_required_parameters() -> None:
    """State travels in named records, not in long argument lists (issue 48's figure): at most
    MAX_REQUIRED_PARAMETERS required parameters, but MANY_PARAMETERS; and each of those still
    takes more."""
    many = {
        name
        for name, node in _package_functions()
        if _required_parameters(node) > MAX_REQUIRED_PARAMETERS
    }
    assert many - set(MANY_PARAMETERS) == set(), sorted(many - set(MANY_PARAMETERS))
    assert set(MANY_PARAMETERS) - many == set(), sorted(set(MANY_PARAMETERS) - many)


def test_the_stages_return_records_and_pass_nothing_mutable() -> None:
    """Each step returns a record of what it computed and found (issue 48, item 1): no function
    in core/stages returns a tuple of more than 3 items, none takes a list, dict or set, and what
    the steps found is a frozen record the pipeline adds up."""
    from handeye_ros.core.checks.verdict import Findings

    wide, mutable = [], []
    for path in sorted((ROOT / 'handeye_ros' / 'core' / 'stages').glob('*.py')):
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.FunctionDef):
                continue
            ret = node.returns
            if (
                isinstance(ret, ast.Subscript)
                and getattr(ret.value, 'id', None) == 'tuple'
                and isinstance(ret.slice, ast.Tuple)
                and len(ret.slice.elts) > 3
            ):
                wide.append(f'{path.name}:{node.name}')
            for arg in node.args.args + node.args.kwonlyargs:
                hint = ast.unparse(arg.annotation) if arg.annotation is not None else ''
                if re.match(r'(list|dict|set)\b', hint):
                    mutable.append(f'{path.name}:{node.name}({arg.arg}: {hint})')
    assert not wide, wide
    assert not mutable, mutable
    assert Findings.__dataclass_params__.frozen  # type: ignore[attr-defined]


def test_the_docs_are_wrapped_at_100_characters() -> None:
    """README.md and docs/*.md read in a terminal: no line over 100 characters (a long command
    is continued with a backslash, a table is a list)."""
    long = [
        f'{path.relative_to(ROOT)}:{k}'
        for path in [ROOT / 'README.md', *sorted((ROOT / 'docs').glob('*.md'))]
        for k, line in enumerate(path.read_text().splitlines(), 1)
        if len(line) > 100
    ]
    assert not long, long


#: What the stages may take from the verdict: its facts, and the decisions a stage needs to go
#: on (and a threshold a warning shares); never a rule that makes a reason.
STAGE_DECISIONS = {
    'Findings',
    'batch_moved',
    'batch_supported',
    'judge_tie',
    'scale_keeps_whole',
    'scale_uncertainty_note',
    'varies_note',
    'WEAK_CORRELATION',
}


def test_facts_in_verdict_out() -> None:
    """The stages record facts (checks/verdict/facts.py) and never make or hold a reason: only
    the verdict reads a fact into one (issue 37, item 2)."""
    from handeye_ros.core.checks.verdict import facts

    allowed = STAGE_DECISIONS | {cls.__name__ for cls in facts.FACTS}
    taken, held = [], []
    for path in sorted((ROOT / 'handeye_ros' / 'core' / 'stages').glob('*.py')):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or '').endswith('verdict'):
                taken += [f'{path.name}: {a.name}' for a in node.names if a.name not in allowed]
            if isinstance(node, ast.Attribute) and node.attr == 'reasons':
                held.append(f'{path.name}:{node.lineno}')
    assert not taken, taken
    assert not held, held


def test_results_md_is_the_summary() -> None:
    """bench/RESULTS.md says where each figure stands in under 600 lines, and links every
    topic file of bench/results/ (the tables behind it)."""
    text = (ROOT / 'bench' / 'RESULTS.md').read_text()
    assert len(text.splitlines()) < 600
    for topic in sorted((ROOT / 'bench' / 'results').glob('*.md')):
        assert f'(results/{topic.name})' in text, topic.name


#: A path of the repository in a comment or docstring: under one of its folders, with a name.
_REPO_PATH = re.compile(
    r'(?<![\w./-])((?:handeye_ros|bench|test|docs|scripts|config|launch|resource)/[\w./-]*\w)'
)


def _comments_and_strings(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every comment and string of a Python file, of every comment of a shell
    script."""
    import io
    import tokenize

    text = path.read_text()
    if path.suffix != '.py':
        return [
            (n, line) for n, line in enumerate(text.splitlines(), 1) if line.lstrip()[:1] == '#'
        ]
    kinds = (tokenize.COMMENT, tokenize.STRING)
    return [
        (tok.start[0], tok.string)
        for tok in tokenize.generate_tokens(io.StringIO(text).readline)
        if tok.type in kinds
    ]


def test_comments_name_only_files_that_exist() -> None:
    """A comment or docstring that names a file of the repository names one that exists (a
    renamed or removed benchmark left its citations behind). bench/out holds what benchmarks
    write (not in git); NAME, TOPIC and x stand for any name."""
    files = [
        *ROOT.glob('handeye_ros/**/*.py'),
        *ROOT.glob('test/**/*.py'),
        *ROOT.glob('bench/*.py'),
        *ROOT.glob('launch/*.py'),
        *(p for p in (ROOT / 'scripts').iterdir() if p.is_file()),
        ROOT / '.ci' / 'run',
        ROOT / 'setup.py',
    ]
    placeholder = re.compile(r'(^|/)([A-Z]+|x)(\.\w+)?$')
    stale = [
        f'{path.relative_to(ROOT)}:{n}: {ref}'
        for path in files
        for n, text in _comments_and_strings(path)
        for ref in (m.group(1).rstrip('.') for m in _REPO_PATH.finditer(text))
        if not (ROOT / ref).exists()
        and not ref.startswith('bench/out')
        and not placeholder.search(ref)
    ]
    assert not stale, stale
