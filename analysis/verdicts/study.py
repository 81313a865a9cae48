"""The verdict study's callback: what ``gyrolab experiment=verdict`` writes once its jobs are done.

``gyrolab experiment=verdict`` (conf/experiment/verdict.yaml) is a Hydra
multirun of two jobs per scene, a dt ladder and a long run.  When they are
done, ``VerdictStudyCallback`` reads every results file of the multirun
directory through analysis/verdicts/verdict.py, bisects the stability thresholds and
writes ``verdict.md``, ``verdict.json`` and ``verdict_<scene>.png`` into that
directory (and into ``docs_dir`` when set, e.g.
``hydra.callbacks.verdict.docs_dir=$PWD/docs``).  The same outputs come from
``gyrolab-verdict <multirun dir> --stability 10 --markdown verdict.md --json
verdict.json --figures DIR``.

The figures are drawn by analysis/verdicts/figures.py.
"""

import sys
import time
from pathlib import Path

try:
    from hydra.experimental.callback import Callback
except ImportError:  # pragma: no cover - hydra is a dependency of the runner
    Callback = object


class VerdictStudyCallback(Callback):
    """After the verdict multirun: verdict.md, verdict.json and figures from its results files.

    stability: T (s) of the threshold bisection; docs_dir: a second directory to write the outputs to
    (None: only the multirun directory)."""

    def __init__(self, stability=10.0, docs_dir=None):
        self.stability = float(stability)
        self.docs_dir = docs_dir

    def on_multirun_end(self, config, **kwargs):
        from .verdict import VerdictError, load, verdict, write_outputs

        if (config.get("runner") or {}).get("dry_run"):  # no files to judge, and nothing failed
            print("gyrolab: verdict: none (dry run; its estimate follows the jobs' estimates)", flush=True)
            return
        root = Path(str(config.hydra.sweep.dir))
        start = time.perf_counter()
        print(f"gyrolab: verdict of {root} (stability bisection over {self.stability:g} s) ...", flush=True)
        try:
            records = verdict([root], stability=self.stability)
            datasets = load([root])
        except VerdictError as err:
            sys.stderr.write(f"gyrolab: verdict skipped: {err}\n")
            return
        for where in [root] + ([Path(self.docs_dir)] if self.docs_dir else []):
            where.mkdir(parents=True, exist_ok=True)
            paths = write_outputs(records, where / "verdict.json", where / "verdict.md", where, datasets)
            print(f"gyrolab: verdict: {', '.join(str(p) for p in paths)}")
        print(f"gyrolab: verdict done in {time.perf_counter() - start:.1f} s", flush=True)
