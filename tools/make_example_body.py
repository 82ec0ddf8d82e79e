"""Write ``examples/bodies/default-female.glb``: the embedded default female body as a skinned GLB.

The example glTF body that docs/getting-started.md builds with
(``seatkit build --template chair --body examples/bodies/default-female.glb``),
written by the project's own exporter (:func:`seatkit.body.gltf.save_gltf_body`)
from the embedded ``default-female`` rig (MakeHuman-derived, CC0; see
``seatkit/data``). ``tests/test_docs.py`` checks the checked-in file is what
this script writes.

    python tools/make_example_body.py [--out examples/bodies/default-female.glb]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from seatkit.body.gltf import save_gltf_body
from seatkit.body.loading import load_rig

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "examples" / "bodies" / "default-female.glb"


def write_example_body(out: Path = DEFAULT_OUT) -> Path:
    """Write the example body to ``out`` and return its path."""
    out.parent.mkdir(parents=True, exist_ok=True)
    return save_gltf_body(out, load_rig("default-female"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    print(write_example_body(ap.parse_args().out))


if __name__ == "__main__":
    main()
