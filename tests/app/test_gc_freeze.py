"""The daemon freezes its start-up objects before the loop, so a full garbage collection in the loop
has only the loop's own objects to traverse."""

from __future__ import annotations

import gc

from app.daemon import freeze_startup_objects


class _Cycle:
    def __init__(self) -> None:
        self.me = self


def test_startup_objects_are_frozen_and_later_garbage_is_still_collected() -> None:
    try:
        freeze_startup_objects()
        assert gc.get_freeze_count() > 1000  # the interpreter, numpy, the app's modules
        for _ in range(100):
            _Cycle()  # reference cycles made after the freeze: only the collector frees them
        assert gc.collect() >= 100
    finally:
        gc.unfreeze()


def test_the_loop_freezes_before_its_first_cycle() -> None:
    import threading

    from app.config import Config
    from app.daemon import ControlLoop
    from vipsm.estimator import Estimator

    loop = ControlLoop(Config(), scanner=None, base=None, camera=None, estimator=Estimator())
    seen: list[int] = []
    loop.step = lambda now_s: seen.append(gc.get_freeze_count())  # type: ignore[method-assign]
    gc.unfreeze()
    try:
        loop.run(threading.Event(), duration_s=0.0)
        assert seen and seen[0] > 1000  # frozen before the first cycle ran
    finally:
        gc.unfreeze()
