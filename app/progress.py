"""Progress bars for long work: the library layers report ``progress(done, total)`` and
know nothing of terminals; the commands and pipelines turn that into a tqdm bar here."""
from __future__ import annotations

from typing import Callable

from tqdm import tqdm


def progress_bar(desc: str, unit: str = "item", enabled: bool = True) -> Callable[[int, int], None] | None:
    """A ``progress(done, total)`` callback that draws a tqdm bar on stderr (what the
    library layers call back with), or None when ``enabled`` is false."""
    if not enabled:
        return None
    bar = None

    def update(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            bar = tqdm(total=total, desc=desc, unit=unit)
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    return update
