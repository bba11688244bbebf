"""Progress of a fit for ``calibrate(..., progress=True)``: a tqdm bar when tqdm is installed
(``tqdm.auto``: a widget in Jupyter, text in a terminal), else one line per stage on stderr.

Any callable ``progress(stage, iteration, objective)`` can be passed instead: ``stage`` names
the solver stage (such as ``"start 1: joint Levenberg-Marquardt"``, ``"particle swarm"``,
``"uncertainty analysis"``; ``"done 2 of 7"`` when a unit of a long job ends: a start, a
probe), ``iteration`` counts the stage's outer iterations from 1 (0 when a stage begins) and
``objective`` is the summed squared marker distance ``e_inner`` in m² (NaN when a stage
begins).
"""

from __future__ import annotations

import math
import sys


class Progress:
    """The default progress display (see the module docs)."""

    def __init__(self) -> None:
        self._bar = None
        self._stage = None
        try:
            from tqdm.auto import tqdm  # type: ignore[import-not-found]
        except ImportError:
            tqdm = None
        self._tqdm = tqdm

    def __call__(self, stage: str, iteration: int, objective: float) -> None:
        if stage.startswith("done "):
            # The end of a unit of a long job: shown on the current bar, no bar of its own.
            if self._bar is not None:
                self._bar.set_postfix_str(stage)
            return
        if stage != self._stage:
            self._stage = stage
            if self._tqdm is None:
                sys.stderr.write(f"jointfit: {stage}\n")
                sys.stderr.flush()
            else:
                if self._bar is not None:
                    self._bar.close()
                self._bar = self._tqdm(desc=stage, unit="it", leave=False)
        if iteration > 0 and self._bar is not None:
            self._bar.update(1)
            if not math.isnan(objective):
                self._bar.set_postfix_str(f"objective {objective:.4e} m²", refresh=False)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
