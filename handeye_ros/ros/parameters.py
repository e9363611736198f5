"""The calibrator's ROS parameters: declared from the option specs (description, range, read
only unless changeable at run time), read into the three configurations, changed at run time,
and names given but unknown (a misspelt key in a params file) said at start."""

from __future__ import annotations

import difflib
import itertools
import os
import re
from dataclasses import replace
from pathlib import Path

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterException,
)
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..app.params_file import REMOVED, RUNTIME_KEYS, RUNTIME_NODE_KEYS, NodeConfig, all_specs
from ..core.config import CalibrationConfig
from ..core.errors import ConfigError, InputError
from ..core.options import Spec, split_options
from ..stream import StreamConfig
from . import files

#: Parameters rclpy declares on every node.
ROS_OWN_PARAMETERS = ('use_sim_time', 'start_type_description_service', 'qos_overrides.')


def descriptor(name: str, spec: Spec) -> ParameterDescriptor:
    """A ParameterDescriptor with the option's description and range."""
    rng = spec.range_text()
    d = ParameterDescriptor(
        name=name,
        description=spec.description + (f' ({rng})' if rng and not spec.choices else ''),
        read_only=name not in RUNTIME_KEYS,
    )
    if spec.choices:
        d.additional_constraints = 'one of: ' + ', '.join(spec.choices)
    if spec.low is not None and spec.high is not None and not spec.optional:
        if spec.kind == 'float':
            d.floating_point_range = [
                FloatingPointRange(from_value=float(spec.low), to_value=float(spec.high), step=0.0)
            ]
        elif spec.kind == 'int':
            d.integer_range = [
                IntegerRange(from_value=int(spec.low), to_value=int(spec.high), step=1)
            ]
    return d


def _default(value: object) -> object:
    # ROS parameters have no null: an optional float is NaN when 'automatic'
    return float('nan') if value is None else value


def declare_and_read(node: Node) -> tuple[CalibrationConfig, StreamConfig, NodeConfig]:
    """Declare every option as a parameter of ``node`` and read the three configurations;
    raises ConfigError naming a parameter whose value is refused."""
    values: dict[str, object] = {}
    defaults = {
        **CalibrationConfig().to_dict(),
        **StreamConfig().to_dict(),
        **NodeConfig().to_dict(),
    }
    for name, spec in all_specs().items():
        try:
            p = node.declare_parameter(name, _default(defaults[name]), descriptor(name, spec))
        except (
            InvalidParameterValueException,
            InvalidParameterTypeException,
            ParameterException,
        ) as err:
            # an integer given for a float: rclpy's types are strict where YAML's are not
            typed = isinstance(err, InvalidParameterTypeException) and spec.kind == 'float'
            hint = ' (write a float with its point: 5.0, not 5)' if typed else ''
            raise ConfigError(f'parameter {name}: {err}{hint}') from None
        values[name] = p.value
    calib, streams, node_cfg = split_options(
        values, (CalibrationConfig, StreamConfig, NodeConfig), source='parameters'
    )
    if node_cfg.auto_calibrate and node_cfg.status_period == 0.0:
        raise ConfigError(
            'auto_calibrate calibrates by the status, which status_period 0 turns off: give '
            'status_period > 0 (1.0 by default), or leave auto_calibrate false'
        )
    return calib, streams, _confined(node_cfg, PATH_KEYS)


#: The node's parameters that name a path to write, each inside ``output_dir`` (:mod:`.files`).
PATH_KEYS = ('output_file', 'report_dir', 'rig_file')


def _confined(cfg: NodeConfig, keys: tuple[str, ...]) -> NodeConfig:
    """``cfg`` with ``output_dir`` made absolute (its default filled in); ConfigError when one
    of ``keys`` leads out of it (``report_dir`` and ``rig_file`` may be empty: off)."""
    root = os.path.abspath(os.path.expanduser(cfg.output_dir or files.default_output_dir()))
    for key in keys:
        value = getattr(cfg, key)
        if value or key == 'output_file':
            try:
                files.inside(root, value, key)
            except InputError as err:
                raise ConfigError(str(err)) from None
    return replace(cfg, output_dir=root)


def apply_changes(
    params: list[Parameter], calib: CalibrationConfig, node_cfg: NodeConfig
) -> tuple[SetParametersResult, CalibrationConfig, NodeConfig]:
    """Run-time parameter changes: (the answer, the new calibration and node
    configurations); a refused value leaves both as they were."""
    changes = {p.name: p.value for p in params if p.name in RUNTIME_KEYS}
    if not changes:
        return SetParametersResult(successful=True), calib, node_cfg
    try:
        ours = {k: v for k, v in changes.items() if k in RUNTIME_NODE_KEYS}
        new_calib = CalibrationConfig.from_mapping(
            {**calib.to_dict(), **{k: v for k, v in changes.items() if k not in ours}},
            source='parameters',
        )
        new_node = NodeConfig.from_mapping({**node_cfg.to_dict(), **ours}, source='parameters')
        new_node = _confined(new_node, tuple(ours))
    except ConfigError as err:
        return SetParametersResult(successful=False, reason=str(err)), calib, node_cfg
    return SetParametersResult(successful=True), new_calib, new_node


def refuse_unknown(node: Node) -> None:
    """Refuse the parameters given (``-p``, a params file) that the node does not have, with
    ConfigError naming the one meant: a misspelt name would otherwise leave its value at the
    default, silently. A removed parameter is only said."""
    given = getattr(node, '_parameter_overrides', {})  # rclpy keeps them only here
    unknown = sorted(
        n for n in given if not node.has_parameter(n) and not n.startswith(ROS_OWN_PARAMETERS)
    )
    said = []
    for name in unknown:
        if name in REMOVED:
            node.get_logger().warning(f'parameter {name!r} ignored: {REMOVED[name]}')
            continue
        near = difflib.get_close_matches(name, list(all_specs()), n=1)
        said.append(f'{name!r}' + (f' (did you mean {near[0]!r}?)' if near else ''))
    if said:
        raise ConfigError(
            f'unknown parameter{"s" if len(said) > 1 else ""} {", ".join(said)}; '
            'calibrator --help lists them'
        )


def warn_unused_params_files(node: Node, argv: list[str]) -> None:
    """Name a params file (``--params-file`` in ``argv``) none of whose sections applies to
    this node: rclpy applies the sections named after the node (or ``/**``) and ignores the
    others silently, so a misnamed section leaves every value at its default."""
    import yaml

    full = node.get_fully_qualified_name()
    for path in (b for a, b in itertools.pairwise(argv) if a == '--params-file'):
        try:
            sections = yaml.safe_load(Path(path).read_text(encoding='utf-8'))
        except (OSError, UnicodeDecodeError, yaml.YAMLError):
            continue  # rclpy has said so already, or refused to start
        if not isinstance(sections, dict):
            continue
        names = [str(k) for k in sections]
        if not any(section_applies(k, full) for k in names):
            near = difflib.get_close_matches(node.get_name(), [k.strip('/') for k in names], 1)
            node.get_logger().warning(
                f'params file {path}: no section for this node ({full}); its sections '
                f'{", ".join(names)} were ignored, every parameter keeps its default'
                + (f' (rename {near[0]!r} to {node.get_name()!r}?)' if near else '')
            )


def section_applies(key: str, node: str) -> bool:
    """Whether a params file's section (``calibrator``, ``/rig/calibrator``, ``/**``,
    ``/**/calibrator``) applies to the fully qualified ``node``, by rcl's wildcards: ``*`` one
    name, ``/**`` any number of namespaces."""
    pattern = re.escape('/' + key.lstrip('/'))
    pattern = pattern.replace(r'/\*\*', '(?:/[^/]+)*').replace(r'\*', '[^/]+')
    return re.fullmatch(pattern, node) is not None
