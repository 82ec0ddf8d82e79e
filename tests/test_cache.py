"""seatkit.cache: the memo caches shared by threads (seatkit serve runs designs on threads)."""

from __future__ import annotations

import gc
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from seatkit.cache import IdentityCache, LRUCache, content_key, value_key


def test_lru_keeps_the_recent_and_drops_the_least_recently_used():
    cache = LRUCache(maxsize=2)
    made = []

    def make(k):
        made.append(k)
        return [k]

    a = cache.get("a", lambda: make("a"))
    cache.get("b", lambda: make("b"))
    assert cache.get("a", lambda: make("a")) is a  # a hit, and now the most recent
    cache.get("c", lambda: make("c"))  # drops b, the least recently used
    assert len(cache) == 2 and made == ["a", "b", "c"]
    assert cache.get("a", lambda: make("a")) is a
    cache.get("b", lambda: make("b"))
    assert made == ["a", "b", "c", "b"]


def test_peek_gives_a_cached_value_without_making_one_or_refreshing_it():
    cache = LRUCache(maxsize=2)
    assert cache.peek("a") is None and len(cache) == 0  # a miss makes nothing
    cache.get("a", lambda: 1)
    cache.get("b", lambda: 2)
    assert cache.peek("a") == 1
    cache.get("c", lambda: 3)  # "a" is still the least recently used: a peek does not refresh it
    assert cache.peek("a") is None and cache.peek("b") == 2 and cache.peek("c") == 3


def test_threads_that_miss_the_same_key_at_once_all_get_one_object():
    cache = LRUCache(maxsize=8)
    barrier = threading.Barrier(6)

    def make():
        barrier.wait(timeout=10)  # every thread is inside make(): all missed
        return object()

    with ThreadPoolExecutor(6) as pool:
        got = list(pool.map(lambda _: cache.get("k", make), range(6)))
    assert len({id(g) for g in got}) == 1 and len(cache) == 1


def test_identity_cache_follows_the_objects_not_their_addresses():
    cache = IdentityCache()
    calls = []

    def make(arr):
        calls.append(1)
        return arr.sum()

    a = np.arange(5.0)
    assert cache.get((a,), lambda: make(a)) == 10.0
    assert cache.get((a,), lambda: make(a)) == 10.0 and len(calls) == 1
    assert cache.get((a,), lambda: make(a) + 1, tag="other") == 11.0 and len(calls) == 2  # tags are separate
    assert cache.get((a.copy(),), lambda: make(a)) == 10.0 and len(calls) == 3  # an equal array is another object
    del a
    gc.collect()
    assert len(cache) == 0  # dropped with its object
    for _ in range(50):  # new arrays at recycled addresses never see an old value
        b = np.full(3, 2.0)
        assert cache.get((b,), lambda: b.sum()) == 6.0
        c = np.full(4, 2.0)
        assert cache.get((c,), lambda: c.sum()) == 8.0
        del b, c


def test_identity_cache_bound_and_unreferenceable_objects():
    cache = IdentityCache(maxsize=2)
    arrays = [np.zeros(i + 1) for i in range(4)]
    for arr in arrays:
        cache.get((arr,), lambda arr=arr: len(arr))
    assert len(cache) == 2
    calls = []
    listed = [1.0, 2.0]  # a list cannot be weakly referenced: made every time, never stored
    for _ in range(3):
        assert cache.get((listed,), lambda: calls.append(1) or 2) == 2
    assert len(calls) == 3 and len(cache) == 2


def test_identity_cache_under_many_threads():
    cache = IdentityCache(maxsize=16)
    arrays = [np.arange(float(i + 1)) for i in range(40)]

    def work(i):
        arr = arrays[i % len(arrays)]
        return cache.get((arr,), lambda: float(arr.sum())) == float(arr.sum())

    with ThreadPoolExecutor(8) as pool:
        assert all(pool.map(work, range(4000)))
    assert len(cache) <= 16


def test_the_library_caches_give_the_same_object_for_the_same_input():
    import trimesh

    from seatkit.geometry.skin import SkinDistance
    from seatkit.subdivision import Cage, build_operators
    from seatkit.template.flat_patch import flat_patch_cage

    sphere = trimesh.creation.icosphere(subdivisions=2)
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    with ThreadPoolExecutor(4) as pool:
        skins = list(pool.map(lambda _: SkinDistance.of(v, f), range(8)))
    assert all(s is skins[0] for s in skins)
    assert SkinDistance.of(v.copy(), f) is not skins[0]
    mesh = flat_patch_cage((-0.2, 0.2), (-0.2, 0.3), 0.4, rows=5, cols=4, margin=0.05)
    cage = Cage.from_control_mesh(mesh)
    with ThreadPoolExecutor(4) as pool:
        ops = list(pool.map(lambda _: build_operators(cage, 2), range(8)))
    assert all(o is ops[0] for o in ops)
    assert cage.base_level() is Cage.from_control_mesh(mesh).base_level()  # same topology, same level


def test_content_key_is_the_same_for_the_same_contents_only():
    a = np.arange(12, dtype=np.float64).reshape(4, 3)
    faces = np.array([[0, 1, 2]])
    assert content_key(a, faces) == content_key(a.copy(), faces.copy()) == content_key(np.asfortranarray(a), faces)
    b = a.copy()
    b[3, 2] = np.nextafter(b[3, 2], np.inf)  # one bit
    assert content_key(b, faces) != content_key(a, faces)
    assert content_key(a.reshape(3, 4), faces) != content_key(a, faces)  # the same bytes, another shape
    assert content_key(a.astype(np.float32), faces) != content_key(a, faces)
    assert content_key(faces, a) != content_key(a, faces)  # in order


def test_value_key_tells_apart_what_a_function_of_such_arguments_could_tell_apart():
    a = np.arange(6, dtype=np.float64)
    state = np.random.default_rng(5).bit_generator.state  # a dict holding integers wider than 64 bits
    args = (a, 0.01, None, "plane", {"x": 1, "y": (2, 3)}, state)
    assert value_key(*args) == value_key(a.copy(), 0.01, None, "plane", {"y": (2, 3), "x": 1}, np.random.default_rng(5).bit_generator.state)
    assert value_key(np.random.default_rng(6).bit_generator.state) != value_key(state)
    assert value_key(1) != value_key("1") != value_key(np.int64(1))  # an int, a string, an array of one
    assert value_key(1.0) != value_key(np.float32(1.0))
    assert value_key((1, 2)) != value_key(1, 2) != value_key((1,), 2)  # nesting counts
    assert value_key(None, 0) != value_key(0, None)  # in order
    b = a.copy()
    b[5] = np.nextafter(b[5], np.inf)
    assert value_key(b) != value_key(a) and value_key(a.reshape(2, 3)) != value_key(a)
