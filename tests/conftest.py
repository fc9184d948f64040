"""Shared fixtures and strategies: random generic cubics and exact test vectors."""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import settings
from hypothesis import strategies as st

from paraloop_core.algebra import factor, poly
from paraloop_core.validation import table1

# CI replays the same examples every run (a red CI is then reproducible, never a dice roll)
settings.register_profile("ci", derandomize=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

E = np.eye(8)
I_, J_, K_, EPS = E[1], E[2], E[3], E[4]
EI, EJ, EK = E[5], E[6], E[7]

#: TV6 (MATH section 13): C = (t - i)(t - 2j - eps i)(t - 3k - eps(i + j)).
TV6_FACTORS = np.array([I_, 2 * J_ + EI, 3 * K_ + EI + EJ])


def random_rotation_factors(rng: np.random.Generator, n: int = 3, batch: tuple = ()) -> np.ndarray:
    """Random rotation factors ``h`` ``(*batch, n, 8)`` (dual scalar 0, moment ⟂ direction)."""
    return table1.random_rotation_factors(rng, batch + (n,))


def random_cubic(rng: np.random.Generator, batch: tuple = ()) -> np.ndarray:
    """A random generic monic cubic ``(*batch, 4, 8)``."""
    return poly.from_factors(random_rotation_factors(rng, 3, batch))


seeds = st.integers(min_value=0, max_value=2**32 - 1)


@pytest.fixture
def tv6() -> np.ndarray:
    return poly.from_factors(TV6_FACTORS)


def assert_generic(c: np.ndarray) -> None:
    """Skip-free guard for property tests: random cubics are generic with probability 1."""
    f = factor.all_factorizations_batch(c)
    assert np.all(f.ok), "random cubic unexpectedly non-generic"


@pytest.fixture(autouse=True)
def _user_data_in_tmp(tmp_path_factory, monkeypatch):
    """Tests never write into the user's data or state folders (studio autosaves, meshes)."""
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path_factory.getbasetemp() / "xdg"))
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path_factory.getbasetemp() / "xdg-state"))


@pytest.fixture(autouse=True, scope="session")
def _no_printed_parts():
    """Studios in tests draw solid links only: the printed parts' builder (``app.printview``,
    a child process of seconds per edit) is switched on by the tests that look at them.
    Session-wide, so that module-scoped studios are built without it too."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("PARALOOP_STUDIO_PARTS", "0")
        yield


def json_paths(node, prefix: tuple = ()):
    """Every path (tuple of keys and indices) into a JSON value, the root ``()`` first."""
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from json_paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from json_paths(v, (*prefix, i))


def json_get(node, path: tuple):
    """The value at ``path`` (:func:`json_paths`) in a JSON value."""
    for k in path:
        node = node[k]
    return node


def numeric_paths(node) -> list[tuple]:
    """Paths of every number (not a bool) in a JSON value."""
    return [p for p in json_paths(node) if isinstance(json_get(node, p), (int, float))
            and not isinstance(json_get(node, p), bool)]
