"""Property-based fuzzing of every loader of a file a user gives (hypothesis).

Each loader gets mutated seeds (seatkit.fuzzing.mutate, its choices drawn by
hypothesis so that a failure shrinks to a small input) and arbitrary bytes.
Whatever the input, the loader either accepts it with every value finite and
in range, or refuses it with seatkit's own error on one line of at most
500 characters that names the file; never another exception, never a hang.
Bounded: about a minute in all (derandomized, so the suite is repeatable);
``tools/fuzz_loaders.py`` runs 10,000 cases per loader (docs/robustness.md).
"""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from seatkit.errors import RecipeError
from seatkit.fuzzing import TARGET_BUILDERS, make_target, run_case
from seatkit.messages import MAX_QUOTE
from seatkit.yamlio import parse_yaml

#: Examples per loader: the glTF body takes about 0.1 s to load, the rest 0.01 s.
EXAMPLES = {"gltf": 60, "bvh": 120, "design": 80, "usd": 120}
DEFAULT_EXAMPLES = 150


class DrawChooser:
    """:class:`seatkit.fuzzing.Chooser` whose choices hypothesis draws (and shrinks)."""

    def __init__(self, data):
        self.data = data

    def randrange(self, n: int) -> int:
        return self.data.draw(st.integers(0, n - 1)) if n > 1 else 0


@pytest.fixture(scope="module")
def targets(tmp_path_factory):
    root = tmp_path_factory.mktemp("fuzz")
    return {name: make_target(name, root / name) for name in TARGET_BUILDERS}, root


def _assert_clean(target, data: bytes, path):
    outcome = run_case(target, data, path, timeout=20.0)
    assert outcome.kind in ("ok", "accepted"), f"{outcome.signature}: {outcome.detail}\ninput: {data[:400]!r}"


def _fuzz_test(name: str):
    @settings(
        max_examples=EXAMPLES.get(name, DEFAULT_EXAMPLES),
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow, HealthCheck.data_too_large],
    )
    @given(data=st.data())
    def test(targets, data):
        built, root = targets
        target = built[name]
        chooser = DrawChooser(data)
        seed = target.seeds[chooser.randrange(len(target.seeds))]
        _assert_clean(target, target.mutate(seed, chooser), root / f"case-{name}{target.suffix}")

    test.__name__ = f"test_mutated_{name}_inputs_are_refused_cleanly_or_accepted_sanely"
    return test


for _name in TARGET_BUILDERS:
    globals()[f"test_mutated_{_name}"] = _fuzz_test(_name)


@settings(max_examples=80, deadline=None, derandomize=True, database=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(blob=st.binary(max_size=3000), name=st.sampled_from(sorted(TARGET_BUILDERS)))
def test_arbitrary_bytes(targets, blob, name):
    built, root = targets
    target = built[name]
    _assert_clean(target, blob, root / f"bytes-{name}{target.suffix}")


@settings(max_examples=300, deadline=None, derandomize=True, database=None)
@given(text=st.text(max_size=400))
def test_parse_yaml_any_text(text):
    """Any text: a Document, or one RecipeError line that never quotes more than it must."""
    try:
        parse_yaml(text, source="any.yaml")
    except RecipeError as e:
        message = str(e)
        assert "\n" not in message and message.startswith("any.yaml")
        assert len(message) <= 3 * MAX_QUOTE + 300


YAML_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4),
    max_leaves=20,
)


@settings(max_examples=150, deadline=None, derandomize=True, database=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(key=st.sampled_from(["template", "bodies", "pressure", "evaluate", "seed", "surface_level", "placement", "refiners", "template_params"]), value=YAML_VALUES)
def test_recipe_any_value_at_any_top_level_key(targets, key, value):
    """A well-formed YAML recipe with any value (any type, NaN, huge) under a real key."""
    import yaml

    built, root = targets
    text = yaml.safe_dump({"template": "chair", key: value}, allow_unicode=True)
    _assert_clean(built["recipe"], text.encode(), root / "typed.yaml")
