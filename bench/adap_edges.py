#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Picture of the neighbour graph of a gradient-domain render (`--neighbours adap`).

    bench/adap_edges.py raw.exr -o edges.png [--crop X Y W H]

Reads the graph from the EXR's difference layers (core/image/gradient_layers.h): `dx` / `dy`
when a lattice direction is complete, else its edges in `edge_1_0` / `edge_0_1`, and every other
offset in `edge_<dx>_<dy>` (NaN where a pixel has no edge). Draws, over the (tone-mapped)
final image of a crop window, every edge as a segment between pixel centres: lattice edges
grey, longer ones orange, and marks in red the lattice edges the graph left out. Prints the
edge counts per offset.
"""
import argparse
import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import OpenImageIO as oiio  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402


def read_layers(path):
    buf = oiio.ImageBuf(path)
    if buf.has_error:
        raise SystemExit(f"{path}: {buf.geterror()}")
    names = list(buf.spec().channelnames)
    pixels = np.asarray(buf.get_pixels(oiio.FLOAT))
    layers = {}
    for i, n in enumerate(names):
        layer, _, channel = n.rpartition(".")
        layers.setdefault(layer, {})[channel] = pixels[:, :, i]
    return layers


def graph_edges(layers, height, width):
    """{(dx, dy): boolean mask of pixels with an edge to pixel + (dx, dy)}."""
    edges = {}
    for name, direction in (("dx", (1, 0)), ("dy", (0, 1))):
        if name in layers:
            mask = np.ones((height, width), bool)
            if direction == (1, 0):
                mask[:, -1] = False
            else:
                mask[-1, :] = False
            edges[direction] = mask
    for name, channels in layers.items():
        m = re.fullmatch(r"edge_(-?\d+)_(-?\d+)", name)
        if m:
            edges[(int(m.group(1)), int(m.group(2)))] = np.isfinite(channels["R"])
    return edges


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("exr")
    ap.add_argument("-o", "--output", default="edges.png")
    ap.add_argument("--crop", nargs=4, type=int, metavar=("X", "Y", "W", "H"),
                    help="window to draw (default: a 48x48 window at the image centre)")
    args = ap.parse_args()

    layers = read_layers(args.exr)
    main_layer = layers[""]
    image = np.stack([main_layer[c] for c in "RGB"], axis=2)
    height, width = image.shape[:2]
    edges = graph_edges(layers, height, width)
    if not edges:
        raise SystemExit(f"{args.exr}: no difference layers (is this a gradient-domain render?)")
    total = sum(int(m.sum()) for m in edges.values())
    print(f"{args.exr}: {width}x{height}, {total} edges, {2 * total / (width * height):.2f} links per pixel")
    for offset in sorted(edges, key=lambda o: (o[1], o[0])):
        print(f"  offset {offset[0]:+d},{offset[1]:+d}: {int(edges[offset].sum())}")

    x0, y0, w, h = args.crop or (max(width // 2 - 24, 0), max(height // 2 - 24, 0), 48, 48)
    x1, y1 = min(x0 + w, width), min(y0 + h, height)
    lattice, longer, missing = [], [], []
    for (dx, dy), mask in edges.items():
        ys, xs = np.nonzero(mask[y0:y1, x0:x1])
        for y, x in zip(ys + y0, xs + x0):
            segment = [(x, y), (x + dx, y + dy)]
            (lattice if abs(dx) + abs(dy) == 1 else longer).append(segment)
    for direction in ((1, 0), (0, 1)):
        mask = edges.get(direction, np.zeros((height, width), bool))
        for y in range(y0, y1):
            for x in range(x0, x1):
                xn, yn = x + direction[0], y + direction[1]
                if xn < width and yn < height and not mask[y, x]:
                    missing.append([(x, y), (xn, yn)])

    tone = np.clip(image / (1.0 + image), 0, 1) ** (1 / 2.2)
    fig, ax = plt.subplots(figsize=(8, 8 * (y1 - y0) / max(x1 - x0, 1)))
    ax.imshow(tone[y0:y1, x0:x1] * 0.6, extent=(x0 - 0.5, x1 - 0.5, y1 - 0.5, y0 - 0.5))
    ax.add_collection(LineCollection(lattice, colors="0.8", linewidths=0.4))
    ax.add_collection(LineCollection(longer, colors="orange", linewidths=0.6))
    ax.add_collection(LineCollection(missing, colors="red", linewidths=1.0))
    ax.set_xlim(x0 - 0.5, x1 - 0.5)
    ax.set_ylim(y1 - 0.5, y0 - 0.5)
    ax.set_title(f"neighbour graph, crop ({x0},{y0}) {x1 - x0}x{y1 - y0}: grey lattice, "
                 "orange longer, red lattice edges left out", fontsize=9)
    ax.set_xticks([])
    ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(args.output, dpi=120)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
