"""The benchmarks' ``--plot`` pictures: each plotting function, given a tiny made-up result,
writes a PNG of the expected size that shows our series and (where the paper prints values)
the paper's, atomically; each bench's ``--help`` offers ``--plot``; a bad path is refused
before the run."""
import os
import sys
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"
if str(BENCH) not in sys.path:
    sys.path.insert(0, str(BENCH))

import crowd_table  # noqa: E402
import ddg  # noqa: E402
import plotting  # noqa: E402
import tiling  # noqa: E402


def rgb(hex_colour):
    return np.array([int(hex_colour[i:i + 2], 16) / 255 for i in (1, 3, 5)])


def read_png(path, width_in, height_in):
    """The RGB pixels of ``path``, checked to be a PNG of the figure size asked for."""
    import matplotlib.image
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = matplotlib.image.imread(str(path))[..., :3]
    assert img.shape[:2] == (round(height_in * plotting.DPI), round(width_in * plotting.DPI))
    assert img.std() > 0.05                        # not a blank page
    return img


def pixels_of(img, colour, tol=0.04):
    """Pixels within ``tol`` of ``colour`` in every channel (anti-aliased text barely reaches it)."""
    return int((np.abs(img - rgb(colour)).max(axis=-1) < tol).sum())


def no_temporaries(d, keep):
    assert sorted(p.name for p in d.iterdir()) == sorted(keep)


def test_figure12_draws_our_curve(tmp_path):
    out = tmp_path / "fig12.png"
    rows = [(0.5, 0.40, False), (1.0, 0.20, True), (2.0, 0.12, True), (4.0, 0.10, True)]
    crowd_table.plot_fig12(rows, str(out), 70, (0.02, 2.0, 1 / 15))
    img = read_png(out, 6.0, 3.9)
    assert pixels_of(img, plotting.OURS) > 150         # the measured curve
    assert pixels_of(img, plotting.FAIL, tol=0.2) > 5  # eps x 0.5 failed the checker: marked
    assert pixels_of(img, plotting.PAPER) == 0         # the paper prints no values for Figure 12
    no_temporaries(tmp_path, ["fig12.png"])
    umask = os.umask(0)
    os.umask(umask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask   # as any new file, not the temporary's 0600


def test_figure11_still_drawn_through_the_shared_helper(tmp_path):
    out = tmp_path / "fig11.png"
    crowd_table.plot_fig11([(3.5, 0.05, True), (3.0, 0.06, True), (2.2, 0.4, False)], str(out), "Figure 11")
    img = read_png(out, 6.0, 3.6)
    assert pixels_of(img, plotting.OURS) > 150


def test_table1_bars_ours_beside_the_papers(tmp_path):
    out = tmp_path / "table1.png"
    table = [("20-2D", 310, 2.5, 40.0), ("20-3D", 290, 2.8, 45.0)]
    costs = [(2, 30.0, 0.5, 0.01), (3, 35.0, 0.6, 0.012)]
    ddg.plot_table1(table, costs, str(out), 120.0, 100)
    img = read_png(out, 13.0, 4.4)
    ours, paper = pixels_of(img, plotting.OURS), pixels_of(img, plotting.PAPER)
    assert ours > 5000                             # our bars, not only their legend swatches
    # the paper's bars (7,200 transitions, 50 MB, 2,200 s) stand taller than these made-up ones
    assert paper > ours


def test_figure7_ours_beside_the_papers(tmp_path):
    out = tmp_path / "fig7.png"
    rows = [(0, 207, 26, 0.01, 0.36, True), (0, 480, 45, 0.05, 1.5, True), (0, 700, 60, 0.2, 4.0, False)]
    tiling.plot_figure7(rows, str(out))
    img = read_png(out, 10.0, 4.2)
    assert pixels_of(img, plotting.OURS) > 1000     # our lines and markers, not only the legend's
    assert pixels_of(img, plotting.PAPER) > 1000    # the paper's five static rows
    assert pixels_of(img, plotting.FAIL, tol=0.2) > 5
    no_temporaries(tmp_path, ["fig7.png"])


def test_a_failed_write_leaves_the_old_picture_and_no_temporary(tmp_path, monkeypatch):
    out = tmp_path / "fig7.png"
    out.write_bytes(b"old")
    fig, _ = plotting.figure()

    def broken(*a, **k):
        raise OSError("disk full")
    monkeypatch.setattr(fig, "savefig", broken)
    with pytest.raises(OSError):
        plotting.save_atomic(fig, str(out))
    assert out.read_bytes() == b"old"
    no_temporaries(tmp_path, ["fig7.png"])


@pytest.mark.parametrize("main", [crowd_table.main, ddg.main, tiling.main], ids=["crowd_table", "ddg", "tiling"])
def test_help_offers_plot(main, capsys):
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    assert "--plot" in capsys.readouterr().out


@pytest.mark.parametrize("main", [crowd_table.main, ddg.main, tiling.main], ids=["crowd_table", "ddg", "tiling"])
@pytest.mark.parametrize("name, why", [("nowhere/out.png", "does not exist"), ("out.jpg", "ending in .png")])
def test_bad_plot_path_refused_before_the_run(main, name, why, tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["--plot", str(tmp_path / name)])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert why in err and name.split("/")[0] in err
