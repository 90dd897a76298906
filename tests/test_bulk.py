"""usdscene.bulk.paused_collection pauses the cyclic collector and leaves it as it found it."""

import gc

import pytest

from usdscene.bulk import paused_collection


@pytest.fixture
def collector_enabled():
    was = gc.isenabled()
    gc.enable()
    yield
    if not was:
        gc.disable()


def test_paused_inside_restored_after(collector_enabled):
    with paused_collection():
        assert not gc.isenabled()
        with paused_collection():  # nested: the inner block must not switch it back on
            assert not gc.isenabled()
        assert not gc.isenabled()
    assert gc.isenabled()


def test_restored_after_an_error(collector_enabled):
    with pytest.raises(KeyError):
        with paused_collection():
            raise KeyError("x")
    assert gc.isenabled()


def test_a_disabled_collector_stays_disabled(collector_enabled):
    gc.disable()
    with paused_collection():
        pass
    assert not gc.isenabled()


def test_cycles_made_inside_are_collected_after(collector_enabled):
    class Node:
        pass

    gc.collect()
    with paused_collection():
        a, b = Node(), Node()
        a.other, b.other = b, a
        del a, b
        assert any(type(o) is Node for o in gc.get_objects())  # the cycle waits
    gc.collect()
    assert not any(type(o) is Node for o in gc.get_objects())
