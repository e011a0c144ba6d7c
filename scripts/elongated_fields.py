"""A second elongated site for the river reach's fix (docs/results/map-quality.md, "Elongated sites: the river reach
again"), made with round 2's GP sampler as scripts/heldout_fields_3.py makes the reach.

    python scripts/elongated_fields.py OUTDIR

writes ``canal.npz`` and ``canal.toml`` (the ``[sim]`` domain and start box). Not used to choose any setting.

``canal.npz``   a dissolved-oxygen concentration in mg/L along a 60 m x 10 m drainage canal (aspect ratio 6, a third of
                the reach's): 8 + 0.6 g, g an anisotropic GP sample (squared exponential, l = 8 m along the canal,
                3 m across, sd ~1); the start box [0, 12] x [0, 10] at one end, so that the swarm sweeps one way
                (the reach starts in the middle). --noise-sd 0.05.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np

from swarmfield.sim.fields import save_npz_field

#: the noise sd the field is run with, in its own units
NOISE_SD = {"canal": 0.05}


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    spec = importlib.util.spec_from_file_location("heldout_fields_2", Path(__file__).with_name("heldout_fields_2.py"))
    r2 = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(r2)
    X, Y, P = r2._lattice(60.0, 10.0, 0.1)
    g = r2._gp_sample(np.random.default_rng(401), P, (8.0, 3.0)).reshape(X.shape)
    save_npz_field(out / "canal.npz", 8.0 + 0.6 * g, (0.0, 60.0, 0.0, 10.0))
    (out / "canal.toml").write_text('preset = "tuned"\n[sim]\ndomain = [0.0, 60.0, 0.0, 10.0]\n'
                                    'start_box = [0.0, 12.0, 0.0, 10.0]\n')
    v = np.load(out / "canal.npz")["values"]
    print(f"canal.npz: min {v.min():.6g} max {v.max():.6g} mean {v.mean():.6g} sd {v.std():.4g} "
          f"(noise sd {NOISE_SD['canal']:g})")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        raise SystemExit(2)
    main(Path(sys.argv[1]))
