"""Property: every registered type's values survive the Zenoh codec (encode -> decode gives an equal value).

Each type's values are drawn from its own ``example()`` by replacing what can vary freely: every
numpy array gets new elements of its dtype and shape (finite floats, small non-negative integers of the dtype),
every float a new finite float, every bool a new bool; strings, integers and the value's
structure stay (they often carry a constraint: an encoding name, a bounded enum). A value the type
refuses (``validate``) is not drawn. A registered type without an example fails the test, so a new
type cannot skip it.
"""

from __future__ import annotations

from typing import Any

import attrs
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from agents_core.errors import AgentsError
from agents_core.messages import values_equal
from agents_core.supported_types import SupportedType, registered_types
from agents_core.types import is_builtin_type

pytest.importorskip("zenoh")

from agents_zenoh.codecs import decode_value, encode_value

pytestmark = pytest.mark.zenoh


def _builtin_types() -> dict[str, type[SupportedType]]:
    # Other tests register their own types in the process-wide registry; only the framework's own
    # types are promised a built-in codec.
    return {n: t for n, t in registered_types().items() if is_builtin_type(t)}


def _like(value: Any) -> st.SearchStrategy[Any]:
    """Values shaped like ``value``: arrays, floats and bools drawn anew, the rest kept."""
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "f":
            elements = st.floats(allow_nan=False, allow_infinity=False, width=8 * value.dtype.itemsize)
            return hnp.arrays(value.dtype, value.shape, elements=elements)
        if value.dtype.kind == "b":
            return hnp.arrays(value.dtype, value.shape)
        if value.dtype.kind in "iu":
            # Small non-negative integers: several types keep unsigned values in signed arrays (ROI corners).
            top = min(255, int(np.iinfo(value.dtype).max))
            return hnp.arrays(value.dtype, value.shape, elements=st.integers(0, top))
        return st.just(value)
    if isinstance(value, bool):
        return st.booleans()
    if isinstance(value, float):
        return st.floats(allow_nan=False, allow_infinity=False)
    if isinstance(value, list):
        return st.tuples(*(_like(v) for v in value)).map(list) if value else st.just([])
    if isinstance(value, tuple):
        return st.tuples(*(_like(v) for v in value))
    if isinstance(value, dict):
        return st.fixed_dictionaries({k: _like(v) for k, v in value.items()})
    if attrs.has(type(value)):
        fields = {f.name: _like(getattr(value, f.name)) for f in attrs.fields(type(value)) if f.init}
        return st.fixed_dictionaries(fields).map(lambda kw: _evolve(value, kw))
    return st.just(value)


#: A drawn value its class refused to build: not a value of the type, so not drawn (``assume``).
_REFUSED = object()


def _evolve(value: Any, changes: dict[str, Any]) -> Any:
    if any(v is _REFUSED for v in changes.values()):
        return _REFUSED
    try:
        return attrs.evolve(value, **changes)
    except (AgentsError, ValueError, TypeError):
        return _REFUSED


@pytest.mark.parametrize("type_name", sorted(_builtin_types()))
def test_values_of_every_registered_type_round_trip_through_the_zenoh_codec(type_name: str) -> None:
    msg_type = _builtin_types()[type_name]
    example = msg_type.example()  # NotImplementedError here: the new type needs an example

    @settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.filter_too_much,
                                                                      HealthCheck.too_slow])
    @given(_like(example))
    def round_trip(drawn: Any) -> None:
        assume(drawn is not _REFUSED)
        try:
            value = msg_type.validate(drawn)
        except (AgentsError, ValueError, TypeError):
            assume(False)
        assert values_equal(decode_value(msg_type, encode_value(msg_type, value)), value)

    round_trip()
