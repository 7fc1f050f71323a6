"""Study benchmarks: the unbinned full-intensity search over all 522 753 light-source pairs, serial, in this
process (numba's kernels use the machine's cores; 2 here). Target: <= 30 s."""
from __future__ import annotations

import os
import time

from dualrgb.simulation.studies.common import SetupSpec, evaluator_for
from dualrgb.simulation.studies.unbinned import unbinned_group_arrays, unbinned_search

TARGET_S = 30.0


def bench_unbinned(mode: str = "reflective", tasks: int = 1) -> dict:
    spec = SetupSpec(mode)
    ev = evaluator_for(spec)
    idx, mask = unbinned_group_arrays(10, 0, 64)                  # JIT / cache warm-up, not timed
    ev.cost_indexed(idx, mask.astype(float))
    load_before = os.getloadavg()
    t = time.perf_counter()
    idx, mask = unbinned_group_arrays(10)
    t_arrays = time.perf_counter() - t
    del idx, mask
    t = time.perf_counter()
    result = unbinned_search(spec, tasks=tasks, top=10, refine=3)
    seconds = time.perf_counter() - t
    best = result.candidates[0]
    return {
        "pairs": result.pairs,
        "seconds": round(seconds, 3),
        "pairs_per_s": round(result.pairs / seconds),
        "us_per_pair": round(1e6 * seconds / result.pairs, 3),
        "index_arrays_s": round(t_arrays, 3),
        "target_s": TARGET_S,
        "within_target": bool(seconds <= TARGET_S),
        "best": {"light1": list(best.sources[0].leds), "light2": list(best.sources[1].leds),
                 "train_de00": round(best.train.mean, 4), "test_de00": round(best.test.mean, 4)},
        "load_average_before": [round(x, 2) for x in load_before],
        "load_average_after": [round(x, 2) for x in os.getloadavg()],
        "cores": os.cpu_count(),
        "numba_threads": int(__import__("numba").get_num_threads()),
        "note": "serial, one process; the load averages show how busy the shared machine was",
    }


if __name__ == "__main__":  # pragma: no cover
    import json

    print(json.dumps(bench_unbinned(), indent=2))
