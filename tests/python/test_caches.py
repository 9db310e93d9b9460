"""The one process-wide memo: bounded, keyed by what the result depends on, listed and emptied."""

from pickplan.core import caches, objects


def test_a_memo_is_bounded_least_recently_used_and_keyed_as_asked():
    calls = []

    @caches.memo(2, key=lambda x, unused: x)
    def square(x, unused):
        calls.append(x)
        return x * x

    assert [square(2, "a"), square(2, "b"), square(3, None)] == [4, 4, 9]
    assert calls == [2, 3]  # the key ignores the second argument
    square(4, None)  # 2 is the least recently used: dropped
    assert square(3, None) == 9 and calls == [2, 3, 4]
    assert square(2, None) == 4 and calls == [2, 3, 4, 2]
    name = f"{__name__}.{square.__qualname__}"
    assert caches.memo_stats()[name] == (2, 2, 4)


def test_clear_memos_rebuilds_a_library_on_its_next_use():
    lib = objects.library("builtin")
    assert objects.library("builtin") is lib
    caches.clear_memos()
    again = objects.library("builtin")
    assert again is not lib and again.names == lib.names
