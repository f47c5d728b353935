"""Writes the demo's drawn pattern, ros_ws/src/rod_deploy/rod_deploy/data/drawn_pattern.png: one pen stroke (a wave,
0.2 m long, 2 cm amplitude) on paper with uneven light, noise and blur, 480 x 320 px at 0.5 mm per pixel with the
table origin at the bottom-left pixel (so the stroke lies at x 0.02-0.22 m, y 0.08-0.12 m, where Baxter's right arm
reaches with the default table pose and a 0.5 m rod). Deterministic; rerun to regenerate."""
from pathlib import Path

import cv2
import numpy as np

from rod_deploy.perception.synthetic import draw_strokes

OUT = Path(__file__).resolve().parents[1] / 'ros_ws/src/rod_deploy/rod_deploy/data/drawn_pattern.png'
M_PER_PX = 0.0005
SHAPE = (320, 480)


def main():
    x = np.linspace(0.02, 0.22, 2000)
    y = 0.10 + 0.02 * np.sin(2 * np.pi * (x - 0.02) / 0.2)
    rows, cols = (SHAPE[0] - 1) - y / M_PER_PX, x / M_PER_PX
    image = draw_strokes(SHAPE, [np.column_stack([rows, cols])], [7.0], [(60, 40, 30)], gradient=0.2,
                         noise_std=1.0, blur_sigma=0.8, seed=3)
    cv2.imwrite(str(OUT), image)
    print(f'wrote {OUT} ({SHAPE[1]} x {SHAPE[0]} px, {M_PER_PX * 1e3:g} mm/px)')


if __name__ == '__main__':
    main()
