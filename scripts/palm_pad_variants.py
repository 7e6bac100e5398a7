"""Diagnostic: copies of hands/pisa_iit_softhand with a compliant palm pad (a guess, never the default model).

The published description has no pad; docs/experiment_table1.md (point 7 of "Why S loses the nominal box and
cylinder") uses these copies to test whether a soft palm would let strategy S carry the nominal box and cylinder.

Variants (folders under --out):
  hand_copy     : unmodified copy (control: must reproduce the published model's verdicts)
  hand_pad5     : pad T = 5 mm on the palm face
  hand_pad10    : pad T = 10 mm on the palm face
  hand_pad10_thenar : pad T = 10 mm + a thenar bulge (extra THENAR_T beyond the pad) on the thumb-side,
                  wrist-side quarter of the palm face (below the thumb base)

Pad: box geom in body "palm" covering the palm box's face (palm frame y -49.0..39.4, z -11.5..113.4 mm), from the
palm face x = 11.6 mm to 11.6 + T mm (palm +x = hand +z, the approach). contype 64 / conaffinity 1 like palm_geom
(collides with objects and the world, not with the digits, so the free closure is unchanged). Contact: priority 2
(beats the object's 0, so the pad's own parameters are used, not averaged), solref "TC 1", solimp "0.5 0.95 0.01",
friction 1.0 0.01 0.001, condim 4 (as the hand's default). Mass 1 g.

Usage: python scripts/palm_pad_variants.py --out DIR       (tc 0.03 s: hand_copy, hand_pad5, hand_pad10,
                                                            hand_pad10_thenar)
       python scripts/palm_pad_variants.py --out DIR --tc 0.05 --suffix _tc05
Then, e.g.: python scripts/guarded_approach.py --hand DIR/hand_pad10/hand.toml --fc none 5 --out pad10.jsonl
"""

from __future__ import annotations

import argparse
import re
import shutil
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "hands" / "pisa_iit_softhand"
FACE = 0.0116  # palm face, palm x [m]
Y0, Y1 = -0.0490, 0.0394
Z0, Z1 = -0.0115, 0.1134
THUMB_BASE_Z = 0.055314  # thumb knuckle z in the palm frame
THENAR_T = 0.006


def box(name: str, x0: float, x1: float, y0: float, y1: float, z0: float, z1: float, tc: float, rgba: str) -> str:
    c = ((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2)
    h = ((x1 - x0) / 2, (y1 - y0) / 2, (z1 - z0) / 2)
    f = lambda v: " ".join(f"{x:.5f}" for x in v)  # noqa: E731
    return (
        f'        <geom name="{name}" type="box" size="{f(h)}" pos="{f(c)}" mass="0.001"\n'
        f'              contype="64" conaffinity="1" priority="2" friction="1.0 0.01 0.001" condim="4"\n'
        f'              solref="{tc} 1" solimp="0.5 0.95 0.01" rgba="{rgba}"/>\n'
    )


def make(out: Path, name: str, T: float, thenar: bool, tc: float) -> None:
    dst = out / name
    if dst.exists():
        shutil.rmtree(dst)
    shutil.copytree(SRC, dst)
    xml = dst / "pisa_iit_softhand.xml"
    text = xml.read_text()
    if T > 0:
        geoms = box("palm_pad", FACE, FACE + T, Y0, Y1, Z0, Z1, tc, "0.9 0.75 0.3 1")
        if thenar:
            # thumb side (palm +y, from the palm centre line to the edge), wrist side up to the thumb base
            geoms += box("thenar_pad", FACE + T, FACE + T + THENAR_T, 0.0, Y1, Z0, THUMB_BASE_Z, tc, "0.9 0.6 0.3 1")
        anchor = '        <geom name="wrist_geom"'
        assert text.count(anchor) == 1
        text = text.replace(anchor, geoms + anchor)
        xml.write_text(text)
    toml = dst / "hand.toml"
    t = toml.read_text()
    t = re.sub(r'^name = ".*"$', f'name = "pisa_iit_softhand_{name}"', t, count=1, flags=re.M)
    toml.write_text(t)
    print(dst, "T =", T, "thenar =", thenar)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True, help="folder for the hand copies")
    ap.add_argument("--tc", type=float, default=0.03, help="pad solref time constant [s]")
    ap.add_argument("--suffix", default="", help="folder suffix for non-default --tc, e.g. _tc05")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    if not a.suffix:
        make(a.out, "hand_copy", 0.0, False, a.tc)
    make(a.out, "hand_pad5" + a.suffix, 0.005, False, a.tc)
    make(a.out, "hand_pad10" + a.suffix, 0.010, False, a.tc)
    make(a.out, "hand_pad10_thenar" + a.suffix, 0.010, True, a.tc)
