"""Regenerate the figures of bench/RESULTS.md and bench/results/*.md from the benchmarks' outputs
(one command).

RESULTS.md says where each figure stands; bench/results/TOPIC.md holds the tables behind it.
Every table a benchmark prints is kept in bench/out/NAME.txt with its provenance line (commit,
versions, seeds; common.emit), and the topic files hold a copy of it between two markers::

    <!-- bench: NAME -->
    ```text
    ...the contents of bench/out/NAME.txt...
    ```
    <!-- /bench -->

This script refills every such block from bench/out (``--run`` first runs the benchmarks that
write them, all of them or those of ``--only``), so a figure in RESULTS.md is always one that a
named command printed on a named commit. The prose that reads the figures is written by hand and
must be re-read after a refill: the script lists the blocks whose figures changed.

Usage:
    python bench/results.py                    # refill RESULTS.md from bench/out
    python bench/results.py --run              # run every registered benchmark, then refill
    python bench/results.py --run --only simulated real
    python bench/results.py --check            # exit 1 when RESULTS.md differs from bench/out
    python bench/results.py --list             # benchmarks, their outputs and their run time
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import time
from pathlib import Path

BENCH = Path(__file__).resolve().parent
OUT = BENCH / 'out'
RESULTS = BENCH / 'RESULTS.md'
#: The files whose generated blocks are refilled: the summary and the topics.
DOCUMENTS = [RESULTS, *sorted((BENCH / 'results').glob('*.md'))]

#: Name -> (benchmark script, its arguments for the figures in RESULTS.md, the outputs it
#: writes, roughly how long it runs on the 2-core reference machine).
BENCHMARKS: dict[str, tuple[str, list[str], list[str], str]] = {
    'simulated': (
        'simulated',
        [],
        [
            'ablation_time_alignment',
            'ablation_linear_*',
            'ablation_pipeline',
            'opencv_level0',
            'opencv_level5',
            'opencv_level10',
            'batch_accuracy',
            'batch_coverage',
            'uncertainty_sim',
            'error_bars',
            'purpose_one_axis',
        ],
        '30 min',
    ),
    'real_cases': ('real_cases', [], ['real_vicon*', 'real_machine_hall*'], '5 min'),
    'coverage_real': ('coverage_real', [], ['coverage_real'], '10 min'),
    'real': (
        'real',
        [],
        [
            'purpose_real',
            'uncertainty_errors',
            'uncertainty_common',
            'uncertainty_pairs',
            'uncertainty_terms',
            'rig_real',
            'rig_real_recordings',
        ],
        '5 min',
    ),
    'live_real': ('live_real', [], ['live_real_evaluation'], '15 min'),
    'live_real_prefixes': (
        'live_real',
        ['--prefixes', '2'],
        ['live_real_prefixes_evaluation'],
        '10 min',
    ),
    'defects': (
        'defects',
        [],
        ['defects_real', 'defects_sim', 'defects_details', 'defects_published'],
        '40 min',
    ),
    'drift_scale': (
        'drift_scale',
        [],
        ['drift_sim', 'scale_sim', 'drift_real', 'scale_real'],
        '20 min',
    ),
    'runtime': ('runtime', [], ['runtime'], '30 min'),
    'runtime_motions': (
        'runtime',
        ['--minutes', '60', '--repeat', '3', '--motion', 'random', 'loops'],
        ['runtime_motions'],
        '10 min',
    ),
    'runtime_motions_10': (
        'runtime',
        ['--minutes', '10', '--hand-rate', '200', '--eye-rate', '30', '--repeat', '5']
        + ['--motion', 'random', 'loops'],
        ['runtime_motions_200_30'],
        '2 min',
    ),
    'runtime_keyframes': (
        'runtime',
        ['--minutes', '2', '10', '30', '--hand-rate', '200', '--eye-rate', '20', '--repeat', '1']
        + ['--keyframes', '0.5'],
        ['runtime_keyframes_200_0.5'],
        '2 min',
    ),
    'evaluate': (
        'evaluate',
        [],
        ['evaluate_many', 'evaluate_report', 'evaluate_real'],
        '20 min',
    ),
    'real_world': (
        'real_world',
        [],
        ['real_world_tumvi', 'real_world_keyframes', 'real_world_sim'],
        '5 min',
    ),
    'node_ingest': (
        'node_ingest',
        [],
        ['node_ingest', 'node_memory', 'node_status_cost', 'node_calibrate', 'offline_bag'],
        '25 min',
    ),
    'node_ingest_default_buffers': (
        'node_ingest',
        ['--skip', 'b', 'c', '--buffer-duration', '1800', '--baseline-minutes', '0'],
        ['node_ingest_buffers1800s', 'node_memory_buffers1800s', 'node_status_cost_buffers1800s'],
        '12 min',
    ),
    'code_path': ('code_path', [], ['code_path'], '5 s'),
    'rig': ('rig', [], ['rig', 'rig_summary'], '2 min'),
}

BLOCK = re.compile(
    r'(?P<open><!-- bench: (?P<name>[\w.-]+) -->\n)```text\n(?P<body>.*?)```\n(?P<close><!-- /bench -->)',
    re.DOTALL,
)


def blocks(text: str) -> list[str]:
    """Names of the generated blocks of a RESULTS.md text, in order."""
    return [m.group('name') for m in BLOCK.finditer(text)]


def refill(text: str, outputs: dict[str, str]) -> tuple[str, list[str], list[str]]:
    """``text`` with every block whose output is in ``outputs`` (name -> contents) replaced;
    returns (new text, names of the blocks that changed, names with no output)."""
    changed: list[str] = []
    missing: list[str] = []

    def fill(m: re.Match) -> str:
        name = m.group('name')
        if name not in outputs:
            missing.append(name)
            return m.group(0)
        body = outputs[name].rstrip('\n') + '\n'
        if body != m.group('body'):
            changed.append(name)
        return f'{m.group("open")}```text\n{body}```\n{m.group("close")}'

    return BLOCK.sub(fill, text), changed, missing


def read_outputs(names: list[str]) -> dict[str, str]:
    """The contents of bench/out/NAME.txt for those names that exist."""
    return {n: (OUT / f'{n}.txt').read_text() for n in names if (OUT / f'{n}.txt').is_file()}


def run(name: str) -> float:
    """Run one benchmark as its own process (its own output on this terminal); seconds."""
    script, args, _, _ = BENCHMARKS[name]
    t0 = time.perf_counter()
    subprocess.run([sys.executable, str(BENCH / f'{script}.py'), *args], check=True)
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--run', action='store_true', help='run the benchmarks before refilling')
    p.add_argument('--only', nargs='+', choices=sorted(BENCHMARKS), help='these benchmarks only')
    p.add_argument('--check', action='store_true', help='exit 1 when RESULTS.md is not current')
    p.add_argument('--list', action='store_true', help='list the benchmarks and their outputs')
    a = p.parse_args(argv)
    if a.list:
        for name, (script, args, outs, took) in BENCHMARKS.items():
            cmd = ' '.join([f'bench/{script}.py', *args])
            print(f'{name:15s} ~{took:7s} {cmd}\n{"":24s}-> bench/out/{{{", ".join(outs)}}}.txt')
        return 0
    if a.run:
        for name in a.only or list(BENCHMARKS):
            print(f'== {name}', flush=True)
            print(f'== {name}: {run(name):.0f} s', flush=True)
    names, changed, missing = [], [], []
    for doc in DOCUMENTS:
        text = doc.read_text()
        found = blocks(text)
        new, changed_here, missing_here = refill(text, read_outputs(found))
        names += found
        changed += changed_here
        missing += missing_here
        if changed_here and not a.check:
            doc.write_text(new)
    for name in missing:
        print(f'no bench/out/{name}.txt: block left as it was', file=sys.stderr)
    if a.check:
        for name in changed:
            print(f'the block {name} differs from bench/out/{name}.txt', file=sys.stderr)
        return 1 if changed else 0
    print(
        f'{len(names)} generated blocks; {len(changed)} refilled'
        + (': ' + ', '.join(changed) + ' (re-read the prose around them)' if changed else '')
    )
    return 0


if __name__ == '__main__':
    sys.exit(main())
