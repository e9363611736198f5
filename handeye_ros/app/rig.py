"""One rig, many recordings: ``offline_calibrate --rig MANIFEST`` and ``evaluate
--shared-extrinsic``.

The recordings of a manifest (:mod:`.runs`) share one T_HE; each keeps its own clock (dt, drift)
and worlds. Two rounds, each one task per recording (:mod:`handeye_ros.core.rig_pipeline` has the
math):

1. :func:`own_calibration`: the recording calibrated alone, as ``offline_calibrate`` does; only
   its :class:`~handeye_ros.core.rig.Member` (estimate and covariance, a few hundred bytes)
   leaves the process that holds its poses.
2. :func:`handeye_ros.core.rig_pipeline.solve_rig` in the calling process: the groups, the joint
   T_HE, the verdict; then :func:`shared_outputs` per recording: its result at the rig's T_HE,
   with the evaluation and the exports computed from it.

On Dask (``evaluate``) a recording's poses stay on the worker that read them between the
rounds; the calling process never holds them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, cast

from ..core.checks.verdict import Code
from .rig_file import RIG_FILE, part_of, read_members, rig_document, write_rig_file

if TYPE_CHECKING:  # imported where used (the rig's math only when a rig is solved)
    from ..core.document import Json, ResultDoc
    from ..core.result import CalibrationResult
    from ..core.rig import Joint, Member
    from ..core.rig_document import RigDoc
    from ..core.rig_pipeline import Rig
    from .runs import RunSpec


@dataclass(frozen=True)
class Own:
    """A recording calibrated alone: its result dictionary and result, or why there is none."""

    name: str
    document: ResultDoc | None
    result: CalibrationResult | None
    reason: str = ''


@dataclass(frozen=True)
class Summary:
    """What the rig needs of a recording's own calibration: its member; or, without one, why,
    and whether it can follow the rig (an offset without a T_HE covariance)."""

    name: str
    member: Member | None
    reason: str
    verdict: str
    follower: bool = False
    purpose: str = ''


def own_calibration(run: RunSpec) -> Own:
    """Round 1: ``run`` (a :class:`~handeye_ros.app.runs.RunSpec`) calibrated alone, no outputs.
    Never raises for bad input: the reason says why it gave nothing."""
    from ..core.errors import HandeyeError
    from .request import run as run_request

    try:
        document, result = run_request(run.request(evaluation=False, progress=False))
    except HandeyeError as err:
        return Own(run.name, None, None, f'it failed: {err}')
    except MemoryError:
        return Own(run.name, None, None, 'it failed: out of memory')
    except Exception as err:  # noqa: BLE001  (a bug: the rig says so and goes on)
        return Own(run.name, None, None, f'internal error: {type(err).__name__}: {err}')
    return Own(run.name, document, result)


def summary_of(own: Own) -> Summary:
    """The member of a recording's own calibration (a failed verdict gives none)."""
    from ..core.rig import Member

    if own.document is None:
        return Summary(own.name, None, own.reason, '')
    q = own.document['quality']
    verdict, purpose = q['verdict'], q['purpose']
    if verdict == 'failed':
        codes = ', '.join(r['code'] for r in q['reasons'])
        return Summary(own.name, None, f'its own calibration failed ({codes})', verdict)
    if not own.document.get('covariance'):
        why = 'no covariance of its own T_HE'
        return Summary(own.name, None, why, verdict, follower=True, purpose=purpose)
    try:
        member = Member.from_document(own.name, own.document)
    except ValueError as err:
        return Summary(own.name, None, str(err), verdict)
    if member.holds_rotation:
        why = 'its motion turned about one axis only: the rotation about it is held, not measured'
        return Summary(own.name, None, why, verdict, follower=True, purpose=purpose)
    return Summary(own.name, member, '', verdict, purpose=purpose)


def at_rig(
    own: Own, joint: Joint | None, member: Member | None, take_rig: bool
) -> tuple[ResultDoc, CalibrationResult]:
    """The recording's result dictionary and result at the rig's T_HE ``joint`` when
    ``take_rig`` (its offset conditioned on it when ``member`` is given, a follower's own
    otherwise), else its own; without the evaluation."""
    from ..core.rig_pipeline import at_shared

    d, result = own.document, own.result
    assert d is not None and result is not None, 'a recording calibrated alone has both'
    doc = d.copy()
    if take_rig and joint is not None:
        result = at_shared(result, joint, member)
        doc.update(
            result.to_dict(
                hand_frame=d['extrinsic']['parent'],
                eye_frame=d['extrinsic']['child'],
                hand_world=d['world_alignment']['child'],
                eye_world=d['world_alignment']['parent'],
            )
        )
        doc['summary'] = result.summary()
        doc['rig'] = {'own': _own_values(d), 'follower': member is None}
    return doc, result


def shared_outputs(
    own: Own,
    joint: Joint | None,
    member: Member | None,
    take_rig: bool,
    folder: str | None,
    report: bool,
) -> ResultDoc | None:
    """Round 2: :func:`at_rig` with the evaluation; writes ``folder``/result.yaml and
    ``folder``/export (and ``folder``/report with ``report``) when ``folder`` is given."""
    from ..evaluation.outputs import evaluate_and_write
    from ..formats.result_file import write_result

    if own.document is None:
        return None
    doc, result = at_rig(own, joint, member, take_rig)
    out = Path(folder) if folder else None
    evaluate_and_write(
        result,
        doc,
        export_dir=out / 'export' if out else None,
        report_dir=out / 'report' if out and report else None,
    )
    if out:
        write_result(out / 'result.yaml', doc)
    return doc


def _own_values(d: ResultDoc) -> dict[str, Json]:
    s = d['std']
    return {
        'time_offset': d['time_offset'],
        'time_offset_std': s['time_offset'] if s else None,
        'translation': list(d['extrinsic']['translation']),
        'rotation': list(d['extrinsic']['rotation']),
        'translation_std': list(s['translation']) if s else None,
        'rotation_std': list(s['rotation']) if s else None,
        'verdict': d['quality']['verdict'],
    }


def calibrate_rig(
    runs: list[RunSpec],
    output: Path | None,
    submit: Callable[..., object] | None = None,
    gather: Callable[[list[object]], list[object]] = list,
) -> tuple[RigDoc, list[ResultDoc | None]]:
    """Both rounds; the rig document and each recording's result dictionary (None when its
    own calibration gave none; written under ``output``/runs/<name>/ when given, with its
    report when the run asks for one).

    ``submit(fn, *args)`` runs a task and returns its handle, and ``gather`` turns handles
    into what the tasks returned: by default here, one recording after the other (the handle
    is the result); on Dask, a client's ``submit`` (pure=False) and ``gather``, so that round
    1's results, poses included, stay on the worker that made them until round 2 runs there,
    and only each recording's summary comes back."""
    run_task = submit or (lambda fn, *args: fn(*args))
    owns = [run_task(own_calibration, r) for r in runs]
    summaries = gather([run_task(summary_of, own) for own in owns])
    rig = solve(cast('list[Summary]', summaries))
    docs = gather(
        [
            run_task(
                shared_outputs, own, rig.joint, *role(rig, r.name), _folder(output, r), r.report
            )
            for r, own in zip(runs, owns, strict=True)
        ]
    )
    results = cast('list[ResultDoc | None]', docs)  # what shared_outputs returned
    return finish(rig, [r.name for r in runs], results, output), results


def solve(summaries: list[Summary]) -> Rig:
    """:func:`~handeye_ros.core.rig_pipeline.solve_rig` on the recordings' summaries."""
    from ..core.checks.verdict import Purpose
    from ..core.rig_pipeline import solve_rig

    members = [s.member for s in summaries if s.member is not None]
    followers = tuple(s.name for s in summaries if s.follower)
    failed = {s.name: s.reason for s in summaries if s.member is None and not s.follower}
    # the stricter purpose when the recordings ask for both: T_HE itself is then the product
    asked = {s.purpose for s in summaries}
    purpose = Purpose.EXTRINSIC if Purpose.EXTRINSIC in asked else Purpose.EVALUATION
    return solve_rig(members, failed, followers, purpose)


def role(rig: Rig, name: str) -> tuple[Member | None, bool]:
    """(its member when it is one the rig's T_HE rests on, whether it takes the rig's T_HE)."""
    k = next((k for k, m in enumerate(rig.members) if m.name == name), None)
    if k is not None and rig.shared[k] is not None:
        return rig.members[k], True
    return None, rig.joint is not None and name in rig.followers


def finish(
    rig: Rig, names: list[str], docs: list[ResultDoc | None], output: Path | None
) -> RigDoc:
    """The rig document, once every recording's result at the rig's T_HE is known (``docs``,
    by ``names``): a follower whose motions the rig's T_HE does not explain is left out;
    written under ``output``."""
    unfit = {}
    for name, doc in zip(names, docs, strict=True):
        if name in rig.followers and doc:
            said = [
                r['message'] for r in doc['quality']['reasons'] if r['code'] == Code.INCONSISTENT
            ]
            if said:
                unfit[name] = said[-1]
    if unfit:
        rig = rig.leaving_out(unfit)
    rig = judged_on_figures(rig, names, docs)
    document = rig_document(rig)
    offsets = {name: doc['time_offset'] for name, doc in zip(names, docs, strict=True) if doc}
    for rec in document['recordings']:
        if rec.get('follows') and rec['name'] in offsets:
            rec['shared'] = {'values': {'time_offset': offsets[rec['name']]}, 'std': {}}
    if output:
        from ..formats.result_file import write_result

        write_result(output / RIG_FILE, document)
    return document


def judged_on_figures(rig: Rig, names: list[str], docs: list[ResultDoc | None]) -> Rig:
    """The rig with purpose evaluation's rule on the figures of the recordings that take its
    T_HE (:func:`~handeye_ros.core.checks.verdict.judge_rig_figures`), from their results
    at it (``docs`` by ``names``; None or unevaluated: not at hand). Unchanged when none of
    them was evaluated."""
    from dataclasses import replace

    from ..core.checks.verdict import judge_rig_figures

    if rig.joint is None:
        return rig
    taking = [n for n in names if n in rig.used or n in rig.followers]
    at_hand = {
        n: d
        for n, d in zip(names, docs, strict=True)
        if n in taking and d and d['quality']['for_evaluation']['figures_judged']
    }
    if not at_hand:
        return rig
    unsettled = {}
    for name, d in at_hand.items():
        q = d['quality']
        if Code.IMPRECISE in q['for_evaluation']['codes']:
            said = [r['message'] for r in q['reasons'] if r['code'] == Code.IMPRECISE]
            unsettled[name] = (
                said[0] if q['purpose'] == 'evaluation' and said else 'see its result'
            )
    quality = judge_rig_figures(rig.quality, unsettled, len(at_hand), len(taking))
    return replace(rig, quality=quality)


def join_rig(
    path: str,
    session: str,
    own: Own,
    evaluate: Callable[[ResultDoc, CalibrationResult], CalibrationResult] | None = None,
) -> tuple[ResultDoc, CalibrationResult]:
    """The node's rig (its ``rig_file`` parameter): this session's own calibration ``own``
    joins the recordings of the rig file at ``path`` (replacing the session's earlier entry;
    the file is made when missing) and the rig is solved again. Returns the session's result
    dictionary and result at the rig's T_HE (its own when it is left out), evaluated by
    ``evaluate`` (which writes the evaluation into the dictionary and returns the result it
    judged) when given, with a ``rig`` section saying what the rig rests on and its verdict
    (on this session's figures: the earlier sessions' poses are gone); writes the file. The
    file keeps the recordings with an estimate of their own (followers and failures are said
    once, in the session's answer). Raises ConfigError when ``path`` holds something else than a rig file."""
    file = Path(path)
    earlier = [Summary(m.name, m, '', '') for m in read_members(file, path) if m.name != session]
    rig = solve([*earlier, summary_of(own)])
    member, take = role(rig, session)
    doc, result = at_rig(own, rig.joint, member, take)
    if evaluate is not None:
        result = evaluate(doc, result)
    names = [s.name for s in earlier] + [session]
    docs: list[ResultDoc | None] = [None] * len(earlier) + [doc]
    document = finish(rig, names, docs, None)
    write_rig_file(file, document)
    r = document['rig']
    part = part_of(r, session)
    doc['summary'] = doc.get('summary') or result.summary()
    doc['summary'] += {
        'used': f'; T_HE of the rig of {len(r["used"])} recordings ({file.name})',
        'follows': f'; T_HE of the rig of {len(r["used"])} recordings ({file.name}): this '
        "session's motion cannot observe it alone",
        'left out': f'; left out of the rig ({file.name}): '
        + r['left_out'].get(session, 'no rig T_HE'),
    }[part]
    doc['rig'] = {
        **doc.get('rig', {}),
        'file': str(file.absolute()),
        'session': session,
        'part': part,
        'recordings': len(r['used']),
        'verdict': r['quality']['verdict'],
        'reasons': [x['message'] for x in r['quality']['reasons']],
    }
    return doc, result


def _folder(output: Path | None, run: RunSpec) -> str | None:
    return str(output / 'runs' / run.slug()) if output else None
