"""Reads a Nimbus EXR (one part: R, G, B, A, stderr.R/G/B/A, nimbus/* header)."""
import numpy as np
import OpenEXR


def read_nimbus_exr(path):
    """Returns (rgb HxWx3 float64, stderr_rgb HxWx3 float64 or None, header dict of str)."""
    with OpenEXR.File(path) as f:
        header = {k: str(v) for k, v in f.header().items()}
        ch = f.channels()
        if "RGBA" in ch:
            rgb = np.array(ch["RGBA"].pixels, dtype=np.float64)[..., :3]
        elif "RGB" in ch:
            rgb = np.array(ch["RGB"].pixels, dtype=np.float64)
        else:
            rgb = np.stack([np.array(ch[c].pixels, dtype=np.float64) for c in "RGB"], -1)
        err = None
        if "stderr" in ch:
            err = np.array(ch["stderr"].pixels, dtype=np.float64)[..., :3]
        elif "stderr.R" in ch:
            err = np.stack([np.array(ch["stderr." + c].pixels, dtype=np.float64) for c in "RGB"], -1)
    return rgb, err, header
