"""Write the bundled YAML/CSV example layouts (run from the repository root).

The grids are the paper's three cases as rectangular lattices of 0.5 m pitch
under a 2.5 m ceiling (the paper's height), dense enough that the paper's
camera sees three LEDs from a hand-held phone.
"""

from pathlib import Path

import yaml

HERE = Path(__file__).parent
PITCH_M = 0.5


def grid(rows: int, cols: int) -> dict:
    lums = [{"name": f"R{r + 1:02d}C{c + 1:02d}", "x": round((c + 0.5) * PITCH_M, 3), "y": round((r + 0.5) * PITCH_M, 3)}
            for r in range(rows) for c in range(cols)]
    return {"unit": "m", "height": 2.5, "radius": 0.1,
            "outline": [[0, 0], [cols * PITCH_M, 0], [cols * PITCH_M, rows * PITCH_M], [0, rows * PITCH_M]],
            "luminaires": lums}


def dump(name: str, doc: dict, comment: str) -> None:
    text = f"# {comment}\n" + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120)
    (HERE / name).write_text(text)


if __name__ == "__main__":
    dump("grid-32.yaml", grid(4, 8), "The paper's 32-LED case: 4 x 8 grid, 0.5 m pitch.")
    dump("grid-256.yaml", grid(16, 16), "The paper's 256-LED case: 16 x 16 grid, 0.5 m pitch.")
    dump("grid-512.yaml", grid(16, 32), "The paper's 512-LED case: 16 x 32 grid, 0.5 m pitch.")
    dump("paper-rig.yaml", {"unit": "cm", "radius": 10, "luminaires": [
        {"name": "N", "x": 0, "y": 30, "z": 250}, {"name": "S", "x": 0, "y": -30, "z": 250},
        {"name": "E", "x": 50, "y": 0, "z": 250}, {"name": "W", "x": -50, "y": 0, "z": 250}]},
        "The paper's test rig (Table 2): four LEDs 2.5 m up; radius 10 cm assumed (not in the paper).\n"
        "# An example of a site that does not work for positioning over a floor: four LEDs cover only poses right\n"
        "# under them (about 21 % with the paper's camera: NOT USABLE); the site advice shows --camera ultrawide.")
    dump("tone-rig.yaml", {"unit": "cm", "height": 246, "radius": 1, "luminaires": [
        {"name": f"T{k + 1}", "x": x, "y": y, "tone_hz": hz} for k, (x, y, hz) in enumerate(
            [(-40, -40, 2000), (40, -40, 2500), (0, 0, 3000), (-40, 40, 3500), (40, 40, 4000)])]},
        "A five-LED research rig, an existing tone site (docs/tones.md): small LEDs about 2 cm across, 2.46 m up,\n"
        "# each blinking a square-wave tone, 2,000-4,000 Hz in 500 Hz steps (issue 37). The positions, a 0.8 m square\n"
        "# and its centre, are assumed. Five LEDs cover few poses with the paper's camera: NOT USABLE, see the advice.")
    dump("outline-room.yaml", {"unit": "m", "height": 2.5, "outline": [[0, 0], [16, 0], [16, 8], [0, 8]]},
         "A 16 m x 8 m room with no luminaires: use with --leds N (about 0.5 m pitch, --leds 512, for the\n"
         "# paper's camera; sparser lattices are NOT USABLE and the site advice says what would work).")
    rows = ["name,x,y,z,radius"] + [f"{'ABC'[r]}{c + 1},{c * 1.2:.1f},{r * 1.2:.1f},2.8,0.1"
                                     for r in range(3) for c in range(4)]
    (HERE / "corridor.csv").write_text(
        "# unit: m\n# A 3 x 4 luminaire corridor, 1.2 m pitch: an example of a site that does not work with the paper's\n"
        "# 50 deg camera (about 9 % of sampled poses see three whole LEDs: NOT USABLE); see the site advice.\n"
        + "\n".join(rows) + "\n")
