"""Writes the demo's drawn pattern, ros_ws/src/rod_deploy/rod_deploy/data/drawn_pattern.png: one pen stroke (a hook:
10 cm straight, then a quarter circle of 7 cm radius, 0.21 m in all) on paper with uneven light, noise and blur,
520 x 280 px at 0.5 mm per pixel with the table origin at the bottom-left pixel, so that the stroke lies from
(0.05, 0.10) m to (0.22, 0.03) m, where Baxter's right arm reaches with the default table pose and a 0.5 m rod (a
pattern that starts straight: a released free end cannot keep a curve, see the README). Deterministic."""
from pathlib import Path

import cv2
import numpy as np

from rod_deploy.perception.synthetic import draw_strokes

OUT = Path(__file__).resolve().parents[1] / 'ros_ws/src/rod_deploy/rod_deploy/data/drawn_pattern.png'
M_PER_PX = 0.0005
SHAPE = (280, 520)


def main():
    straight = np.column_stack([np.linspace(0.05, 0.15, 1000), np.full(1000, 0.10)])
    angle = np.linspace(0.0, np.pi / 2, 1000)[1:]
    arc = np.column_stack([0.15 + 0.07 * np.sin(angle), 0.10 - 0.07 * (1.0 - np.cos(angle))])
    x, y = np.vstack([straight, arc]).T
    rows, cols = (SHAPE[0] - 1) - y / M_PER_PX, x / M_PER_PX
    image = draw_strokes(SHAPE, [np.column_stack([rows, cols])], [7.0], [(60, 40, 30)], gradient=0.2,
                         noise_std=1.0, blur_sigma=0.8, seed=3)
    cv2.imwrite(str(OUT), image)
    print(f'wrote {OUT} ({SHAPE[1]} x {SHAPE[0]} px, {M_PER_PX * 1e3:g} mm/px)')


if __name__ == '__main__':
    main()
