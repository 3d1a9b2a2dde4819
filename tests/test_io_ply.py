"""PLY writer/reader round trip and bad input (edge.io.ply)."""

import numpy as np
import pytest

from edge.io.ply import read_ply, write_ply


@pytest.mark.parametrize("binary", [True, False])
@pytest.mark.parametrize("with_colors", [True, False])
def test_round_trip(tmp_path, binary, with_colors):
    rng = np.random.default_rng(0)
    xyz = rng.normal(size=(257, 3)).astype(np.float64)
    colors = rng.integers(0, 256, size=(257, 3), dtype=np.uint8) if with_colors else None
    path = write_ply(tmp_path / "c.ply", xyz, colors=colors, binary=binary)
    got, got_colors = read_ply(path)
    # the file declares float32 x y z: both formats give back the float32 points bit for bit (the
    # ASCII writer printed 6 significant digits, about 5e-6 off here, under the old rtol of 1e-5)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, xyz.astype(np.float32))
    if with_colors:
        np.testing.assert_array_equal(got_colors, colors)
    else:
        assert got_colors is None
    header = path.read_bytes().split(b"end_header")[0].decode()
    assert "element vertex 257" in header


def test_bad_input(tmp_path):
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        write_ply(tmp_path / "x.ply", np.zeros((4, 2)))
    with pytest.raises(ValueError, match="uint8"):
        write_ply(tmp_path / "x.ply", np.zeros((4, 3)), colors=np.zeros((4, 3)))
    path = write_ply(tmp_path / "t.ply", np.zeros((10, 3)))
    path.write_bytes(path.read_bytes()[:-5])
    with pytest.raises(ValueError, match="truncated"):
        read_ply(path)
    (tmp_path / "n.ply").write_bytes(b"hello")
    with pytest.raises(ValueError, match="not a PLY"):
        read_ply(tmp_path / "n.ply")
