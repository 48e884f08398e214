#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Image metrics shared by the bench scripts.

relative MSE = mean over pixels and RGB channels of (x - ref)^2 / (ref^2 + 0.01), the metric of
../shared/references/README.md.
"""
import sys

import numpy as np
import OpenImageIO as oiio


def read_rgb(path, layer=""):
    """Float32 HxWx3 array of an EXR's main layer (or of the layer named `layer`)."""
    buf = oiio.ImageBuf(path)
    if buf.has_error:
        raise RuntimeError(f"{path}: {buf.geterror()}")
    spec = buf.spec()
    names = list(spec.channelnames)
    wanted = ["R", "G", "B"] if not layer else [f"{layer}.R", f"{layer}.G", f"{layer}.B"]
    idx = [names.index(n) for n in wanted]
    pixels = buf.get_pixels(oiio.FLOAT)
    return np.asarray(pixels)[:, :, idx].astype(np.float64)


LUMINANCE = (0.212671, 0.715160, 0.072169)  # Rec. 709, as core/math/types.h luminance()


def read_luminance(path, layer):
    """HxW luminance of an RGB layer, or the layer itself when it has one channel (`name.Y`,
    e.g. the variance layers, which hold the variance of the luminance)."""
    buf = oiio.ImageBuf(path)
    names = list(buf.spec().channelnames)
    pixels = np.asarray(buf.get_pixels(oiio.FLOAT)).astype(np.float64)
    if f"{layer}.Y" in names:
        return pixels[:, :, names.index(f"{layer}.Y")]
    rgb = read_rgb(path, layer)
    return rgb @ np.array(LUMINANCE)


def write_rgb(path, image):
    """Writes an HxWx3 array as a float RGB EXR."""
    spec = oiio.ImageSpec(image.shape[1], image.shape[0], 3, oiio.FLOAT)
    buf = oiio.ImageBuf(spec)
    buf.set_pixels(oiio.ROI(), np.ascontiguousarray(image, dtype=np.float32))
    if not buf.write(path):
        raise RuntimeError(f"{path}: {buf.geterror()}")


def forward_differences(image):
    """(dx, dy) as the dx/dy layers hold them: I(x+1) - I(x) and I(y+1) - I(y), 0 on the last
    column / row."""
    dx = np.zeros_like(image)
    dy = np.zeros_like(image)
    dx[:, :-1] = image[:, 1:] - image[:, :-1]
    dy[:-1, :] = image[1:, :] - image[:-1, :]
    return dx, dy


def rel_mse(image, reference):
    return float(np.mean((image - reference) ** 2 / (reference ** 2 + 0.01)))


def box_downsample(image, factor=8):
    """Mean over factor x factor blocks of an HxWxC image (rows and columns beyond the last
    whole block are dropped)."""
    h, w = image.shape[0] - image.shape[0] % factor, image.shape[1] - image.shape[1] % factor
    if h == 0 or w == 0:
        raise ValueError(f"image {image.shape[:2]} is smaller than one {factor}x{factor} block")
    blocks = image[:h, :w].reshape(h // factor, factor, w // factor, factor, -1)
    return blocks.mean(axis=(1, 3))


def low_pass_rel_mse(image, reference, factor=8):
    """rel_mse of the factor x factor box-downsampled image against the same downsampling of
    the reference: the error left at coarse scales, where pixel noise has averaged out and
    bias, lost energy or blotches remain."""
    return rel_mse(box_downsample(image, factor), box_downsample(reference, factor))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: metrics.py image.exr reference.exr")
    a, b = read_rgb(sys.argv[1]), read_rgb(sys.argv[2])
    print(f"relMSE {rel_mse(a, b):.6g}  mean {a.mean(axis=(0, 1))}  ref mean {b.mean(axis=(0, 1))}")
