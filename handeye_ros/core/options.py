"""Declarative option sets: one description, range and type per option, used everywhere.

An option set is a frozen dataclass whose fields are made with :func:`option`. The same
metadata validates values (:meth:`Options.validate`, run on construction), parses mappings
from YAML files or node parameters (:meth:`Options.from_mapping`), documents command-line
options, and gives the node its ParameterDescriptors (description and range), so a name, a
bound or a sentence is written once.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from typing import TYPE_CHECKING, TypedDict, TypeVar, Unpack, overload

from .document import Json
from .errors import ConfigError

if TYPE_CHECKING:  # typing.Self is 3.11+; annotations here are never evaluated
    from typing import Self


@dataclass(frozen=True)
class Spec:
    """What an option accepts.

    kind: 'float', 'int', 'bool' or 'str'; optional: None (or NaN) is allowed and means
    'automatic'; low/high: inclusive bounds, except low when open_low; choices: allowed strings;
    alias: a second, shorter command-line flag; expert: an option few users need (fine tuning
    of a stage): the command line lists it under --help-all. ablation: a switch that undoes one
    of the method's steps to measure what it brings (the paper's ablations): no user option at
    all (not on the command line, not a node parameter, not in a params or --config file); only
    the benchmarks and the tests set it, by constructing the option set.
    """

    kind: str
    description: str
    low: float | None = None
    high: float | None = None
    open_low: bool = False
    optional: bool = False
    choices: tuple[str, ...] = ()
    alias: str = ''  # a shorter command-line flag, e.g. 'scale' for --estimate-scale
    expert: bool = False
    ablation: bool = False

    def range_text(self) -> str:
        """Human form of the bounds, e.g. '(0, 90]'."""
        if self.choices:
            return ' | '.join(self.choices)
        if self.low is None and self.high is None:
            return ''

        def num(v: float) -> str:
            return f'{int(v):d}' if self.kind == 'int' else f'{v:g}'

        lo = '-inf' if self.low is None else num(self.low)
        hi = 'inf' if self.high is None else num(self.high)
        return f'{"(" if self.open_low else "["}{lo}, {hi}{"]" if self.high is not None else ")"}'


class SpecFields(TypedDict, total=False):
    """:class:`Spec`'s fields after kind and description, as :func:`option` takes them."""

    low: float | None
    high: float | None
    open_low: bool
    optional: bool
    choices: tuple[str, ...]
    alias: str
    expert: bool
    ablation: bool


_T = TypeVar('_T')


def option(default: _T, kind: str, description: str, **spec: Unpack[SpecFields]) -> _T:
    """A dataclass field carrying its :class:`Spec` (typed as its default, as
    ``dataclasses.field`` is)."""
    return field(default=default, metadata={'spec': Spec(kind, description, **spec)})


class Options:
    """Base of the option dataclasses (see the module docstring)."""

    def __post_init__(self) -> None:
        self.validate()

    @classmethod
    def specs(cls) -> dict[str, Spec]:
        """The user's options: name -> Spec, in declaration order (no ablation switch)."""
        return {n: s for n, s in cls._every_spec().items() if not s.ablation}

    @classmethod
    def _every_spec(cls) -> dict[str, Spec]:
        return {f.name: f.metadata['spec'] for f in fields(cls)}  # type: ignore[arg-type]

    def validate(self) -> None:
        """Raise ConfigError naming the first option whose value is out of its range."""
        for name, spec in self._every_spec().items():
            _check(name, getattr(self, name), spec)

    @classmethod
    def from_mapping(cls, values: Mapping[str, object], source: str = 'config') -> Self:
        """Options from a mapping (a parsed YAML file or node parameters).

        Unknown keys are refused (a typo must not silently fall back to a default); for an
        optional option, null or NaN means 'automatic'. Errors name ``source`` and the option.
        """
        if not isinstance(values, Mapping):
            msg = f'{source}: expected a mapping of option names to values'
            raise ConfigError(msg)
        specs = cls.specs()
        _refuse_unknown(values, list(specs), source)
        clean = {k: _coerce(k, v, specs[k], source) for k, v in values.items()}
        try:
            return replace(cls(), **clean)  # type: ignore[type-var]
        except ConfigError as err:
            raise ConfigError(f'{source}: {err}') from None

    def to_dict(self) -> dict[str, Json]:
        """The user's options' plain values, the inverse of :meth:`from_mapping`."""
        values: dict[str, Json] = asdict(self)  # type: ignore[call-overload]
        return {k: v for k, v in values.items() if k in self.specs()}

    def ablations(self) -> dict[str, Json]:
        """The ablation switches set away from their defaults (a benchmark's), by name."""
        values: dict[str, Json] = asdict(self)  # type: ignore[call-overload]
        default = asdict(type(self)())  # type: ignore[call-overload]
        every = self._every_spec()
        return {k: v for k, v in values.items() if every[k].ablation and v != default[k]}


def _refuse_unknown(values: Mapping[str, object], known: list[str], source: str) -> None:
    """ConfigError naming the keys of ``values`` not in ``known``: a typo must not silently
    fall back to a default."""
    unknown = sorted(set(values) - set(known))
    if unknown:
        msg = (
            f'{source}: unknown option(s) {", ".join(unknown)}; known options are '
            f'{", ".join(known)}'
        )
        raise ConfigError(msg)


def _coerce(key: str, value: object, spec: Spec, source: str) -> object:
    if spec.optional and (value is None or (isinstance(value, float) and math.isnan(value))):
        return None
    ok = {
        'bool': isinstance(value, bool),
        'int': isinstance(value, int) and not isinstance(value, bool),
        'float': isinstance(value, (int, float)) and not isinstance(value, bool),
        'str': isinstance(value, str),
    }[spec.kind]
    if not ok:
        msg = f'{source}: option {key} must be of type {spec.kind}, got {value!r}'
        raise ConfigError(msg)
    return float(value) if spec.kind == 'float' and isinstance(value, int | float) else value


def _check(name: str, value: object, spec: Spec) -> None:
    if value is None:
        if spec.optional:
            return
        msg = f'option {name} must be set'
        raise ConfigError(msg)
    if spec.choices:
        if value not in spec.choices:
            msg = f'option {name} must be one of {", ".join(spec.choices)}; got {value!r}'
            raise ConfigError(msg)
        return
    if spec.kind not in ('float', 'int'):
        return
    if not isinstance(value, int | float) or isinstance(value, bool):
        msg = f'option {name} must be a number; got {value!r}'
        raise ConfigError(msg)
    if not math.isfinite(value):
        msg = f'option {name} must be a finite number; got {value!r}'
        raise ConfigError(msg)
    low, high = spec.low, spec.high
    too_low = low is not None and (value <= low if spec.open_low else value < low)
    if too_low or (high is not None and value > high):
        msg = f'option {name} must lie in {spec.range_text()}; got {value!r}'
        raise ConfigError(msg)


_A = TypeVar('_A', bound='Options')
_B = TypeVar('_B', bound='Options')
_C = TypeVar('_C', bound='Options')


@overload
def split_options(
    values: Mapping[str, object], classes: tuple[type[_A], type[_B]], source: str = ...
) -> tuple[_A, _B]: ...
@overload
def split_options(
    values: Mapping[str, object], classes: tuple[type[_A], type[_B], type[_C]], source: str = ...
) -> tuple[_A, _B, _C]: ...
def split_options(
    values: Mapping[str, object], classes: tuple[type[Options], ...], source: str = 'config'
) -> tuple[Options, ...]:
    """One flat mapping (a params file, node parameters, command-line options) as one instance
    of each option set in ``classes``; a key none of them knows is refused, naming ``source``.
    """
    _refuse_unknown(values, [name for cls in classes for name in cls.specs()], source)
    return tuple(
        cls.from_mapping({k: v for k, v in values.items() if k in cls.specs()}, source)
        for cls in classes
    )
