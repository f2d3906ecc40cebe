"""Cost of the ParaView fields: a drop test with ``--vtu`` fields at 5 kHz against the same run
without frames, in one process (issue 21, item 5: less than 20 % more wall time).

    python -m cfm_verification.benchmarks.fields [--size 0.001] [--thickness 0.008] [--backend numba] [--repeat 2]

Each repeat runs the model without frames, then with ``frame_interval = 2e-4`` s (5 kHz) followed
by writing every field of every frame (:func:`cfm_core.post.vtu.write_field_series`, default
fields, quarter model) into a temporary folder; kernels are compiled before the first timing.
Prints both wall times (s), the best of the repeats, and the overhead. Timings on a loaded
machine are noisy: check ``uptime`` first.
"""

from __future__ import annotations

import argparse
import tempfile
import time

#: Target of issue 21, item 5: extra wall time of writing fields at 5 kHz, fraction of the run.
TARGET = 0.20


def main(argv=None) -> int:
    """Run the benchmark; 0 when the overhead is below :data:`TARGET`, else 1."""
    from cfm_core.post.fields import DEFAULT_FIELDS
    from cfm_core.post.vtu import write_field_series
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import builtin_scene
    from cfm_core.simulation.registry import backend_for

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=float, default=0.001, help="element size, m")
    p.add_argument("--thickness", type=float, default=0.008, help="specimen thickness, m")
    p.add_argument("--backend", default="numba")
    p.add_argument("--repeat", type=int, default=2)
    a = p.parse_args(argv)
    model = build_model(builtin_scene("drop-test").with_overrides(element_size=a.size, thickness=a.thickness))
    backend = backend_for(a.backend)
    backend.run(model, frame_interval=2e-4)   # compile / warm up
    plain, fields, write, frames = [], [], [], 0
    for _ in range(a.repeat):
        t0 = time.perf_counter()
        backend.run(model)
        plain.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        res = backend.run(model, frame_interval=2e-4)
        t1 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            write_field_series(tmp, model, res, DEFAULT_FIELDS)
        t2 = time.perf_counter()
        fields.append(t2 - t0)
        write.append(t2 - t1)
        frames = len(res.frames)
    base, withf = min(plain), min(fields)
    over = withf / base - 1.0
    print(f"drop test {1e3 * a.thickness:g} mm, {1e3 * a.size:g} mm elements ({model.n_elements} elements), "
          f"{a.backend}: run without frames {base:.3f} s; with {frames} frames at 5 kHz and all fields written "
          f"{withf:.3f} s (writing {min(write):.3f} s): overhead {100 * over:.1f} % (target < {100 * TARGET:.0f} %)")
    return 0 if over < TARGET else 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
