"""Compiled kernels whose on-disk cache cannot be written still run (the cache is only an
optimisation): a cold cache under a file size limit, as on a full disk."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent("""
    import resource, signal
    import numpy as np
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # as the command line does: EFBIG, not a kill
    resource.setrlimit(resource.RLIMIT_FSIZE, (512, 512))
    from usdscene.labels.amodal import amodal_projection
    from usdscene.document.model import Camera, Intrinsics, LensModel
    camera = Camera("cam", Intrinsics(LensModel.FISHEYE_EQUISOLID, 64, 48, 20.0, 20.0, 31.5, 23.5, fov_deg=120.0))
    square = np.array([[[-0.5, -0.5, 2.0], [0.5, -0.5, 2.0], [0.5, 0.5, 2.0]],
                       [[-0.5, -0.5, 2.0], [0.5, 0.5, 2.0], [-0.5, 0.5, 2.0]]])
    print("pixels", amodal_projection(camera, square).pixel_count)
""")


def test_kernels_run_when_their_disk_cache_cannot_be_written(tmp_path):
    cache = tmp_path / "numba-cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    result = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    pixels = int(result.stdout.split()[-1])
    assert 50 < pixels < 400
    assert "not cached on disk (File too large)" in result.stderr
