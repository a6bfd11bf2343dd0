"""Tests of pfmembrane.analysis.plot on synthetic checkpoints of an ellipse."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.image  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pfmembrane.io import checkpoint
from pfmembrane.analysis import field3d, levelset, plot  # noqa: E402

BOX = (1.0, 2.0)
A, B, ZC = 0.5, 0.8, 1.0  # semi-axes along r and z, centre height
TIMEOUT = 60


def ellipse_checkpoint(path, eps, seed=0):
    """Write a checkpoint of phi = tanh(d / (sqrt(2) eps)) for an ellipse,
    on a coarse grid plus nodes clustered at the membrane."""
    rng = np.random.default_rng(seed)
    rb, zb = BOX
    r, z = np.meshgrid(np.linspace(0.0, rb, 11), np.linspace(0.0, zb, 21))
    t = rng.uniform(0.0, np.pi, 300)
    scale = 1.0 + 0.08 * rng.standard_normal(300)
    band = np.column_stack([A * scale * np.sin(t), ZC + B * scale * np.cos(t)])
    band = band[(band[:, 0] > 0.0) & (band[:, 0] < rb)]
    nodes = np.vstack([np.column_stack([r.ravel(), z.ravel()]), band])
    # Signed distance to the ellipse, to first order in the radial defect.
    d = min(A, B) * (1.0 - np.hypot(nodes[:, 0] / A, (nodes[:, 1] - ZC) / B))
    phi = np.tanh(d / (np.sqrt(2.0) * eps))
    attrs = {"energy": 8.0 * np.pi, "area": 4.0, "volume": 1.0,
             "moment": 0.0, "eps": eps, "k": 1.0, "c0": 0.0, "gamma": 0.8,
             "cutoff": 1e-6,
             "nu_area": 0.0, "nu_volume": 0.0, "converged": 1,
             "wall_time": 1.0, "box": BOX}
    checkpoint.write(path, nodes, phi, attrs)
    return checkpoint.read(path)


@pytest.fixture
def pair(tmp_path):
    """Two checkpoints of the same ellipse with different eps."""
    paths = [tmp_path / "thin.h5", tmp_path / "thick.h5"]
    ckpts = [ellipse_checkpoint(path, eps)
             for path, eps in zip(paths, (0.03, 0.08))]
    return paths, ckpts


@pytest.fixture
def run_plot(python):
    """`python -m pfmembrane.analysis.plot ARGS...`, in `cwd` (None: this
    process's working directory)."""
    def run(*args, cwd=None):
        return python("-m", "pfmembrane.analysis.plot", *args, cwd=cwd,
                      timeout=TIMEOUT)
    return run


def assert_picture(path, min_bytes=10_000):
    """The PNG exists, is not tiny and shows more than one colour."""
    assert path.stat().st_size > min_bytes, path
    pixels = matplotlib.image.imread(path)
    colours = np.unique(pixels.reshape(-1, pixels.shape[-1]), axis=0)
    assert len(colours) > 20, path


@pytest.mark.slow
def test_cli_writes_every_figure(pair, tmp_path, run_plot):
    paths, _ = pair
    outdir = tmp_path / "figures"

    # A low resolution keeps the nine figures quick to render.
    result = run_plot(*paths, "-o", outdir, "--dpi", 80)

    assert result.returncode == 0, result.stderr
    expected = [outdir / f"{path.stem}_{what}.png"
                for what in plot.FIGURES for path in paths
                if what != "section" or path == paths[0]]
    assert result.stdout.split() == [str(path) for path in expected]
    assert sorted(outdir.iterdir()) == sorted(expected)
    for path in expected:
        assert_picture(path, min_bytes=5_000)


@pytest.mark.slow
def test_cli_selected_figures_beside_checkpoint(pair, tmp_path, run_plot, root):
    paths, _ = pair

    result = run_plot(paths[1], "--what", "section,field", cwd=root)

    assert result.returncode == 0, result.stderr
    written = [tmp_path / "thick_section.png", tmp_path / "thick_field.png"]
    assert result.stdout.split() == [str(path) for path in written]
    assert {p.name for p in tmp_path.glob("*.png")} == {p.name
                                                        for p in written}
    for path in written:
        assert_picture(path)


@pytest.mark.slow
def test_cli_rejects_unknown_figure(pair, run_plot):
    paths, _ = pair

    result = run_plot(paths[0], "--what", "field,movie")

    assert result.returncode == 2
    assert "unknown figure movie" in result.stderr


@pytest.mark.slow
def test_cli_reports_unreadable_checkpoint(tmp_path, run_plot):
    bad = tmp_path / "bad.h5"
    bad.write_text("not a checkpoint")

    result = run_plot(bad)

    assert result.returncode == 1
    assert f"cannot read checkpoint {bad}: not an HDF5 file" in result.stderr
    assert list(tmp_path.glob("*.png")) == []


def membrane(ax):
    """The membrane polylines plot_field drew, on r >= 0 and mirrored."""
    return [line.get_xydata() for line in ax.get_lines()
            if line.get_label() == "_membrane"]


def test_the_membrane_is_phi_h_zero_round_the_ellipse(pair):
    _, (thin, _) = pair

    ax = plot.plot_field(thin, nodes=False)

    right, left = membrane(ax)
    np.testing.assert_array_equal(left, right * [-1.0, 1.0])
    radius = np.hypot(right[:, 0] / A, (right[:, 1] - ZC) / B)
    np.testing.assert_allclose(radius, 1.0, atol=0.05)
    # From the axis at the bottom pole round to the axis at the top pole.
    assert np.isclose(right[:, 1].min(), ZC - B, atol=0.05)
    assert np.isclose(right[:, 1].max(), ZC + B, atol=0.05)
    assert right[:, 0].max() == pytest.approx(A, abs=0.05)
    plt.close(ax.figure)


def test_section_crosses_zero_at_the_membrane(pair):
    _, ckpts = pair

    ax = plot.plot_section(ckpts)

    lines = [line for line in ax.get_lines() if line.get_label()[0] != "_"]
    assert [line.get_label() for line in lines] == ["eps = 0.03",
                                                    "eps = 0.08"]
    for line in lines:
        r, phi = line.get_xydata().T
        assert phi[0] > 0.99 and phi[-1] < -0.99
        crossing = r[np.argmax(phi < 0.0)]
        assert crossing == pytest.approx(A, abs=0.02)
    plt.close(ax.figure)


def test_field_mirrors_and_marks_nodes(pair):
    _, (thin, _) = pair

    ax = plot.plot_field(thin, nodes=True)

    [dots] = [line for line in ax.get_lines() if line.get_label() != "_membrane"]
    np.testing.assert_array_equal(dots.get_xdata(), -thin.nodes[:, 0])
    # the colours are phi_h at the nodes, not the coefficients it does not interpolate
    phi_h = levelset.PhaseField(thin)(thin.nodes)
    assert np.max(np.abs(phi_h - thin.phi)) > 1e-3
    for colours in ax.collections[:2]:
        np.testing.assert_array_equal(colours.get_array(), phi_h)
    assert ax.get_xlim() == (-BOX[0], BOX[0])
    plt.close(ax.figure)
    bare = plot.plot_field(thin, nodes=False)
    assert len(bare.get_lines()) == len(membrane(bare)) == 2
    plt.close(bare.figure)


def test_a_field_without_a_membrane_is_drawn_without_one(pair):
    _, (thin, _) = pair
    empty = checkpoint.Checkpoint(nodes=thin.nodes, phi=-np.ones(len(thin.nodes)),
                                  attrs=thin.attrs)

    ax = plot.plot_field(empty, nodes=False)

    assert membrane(ax) == []
    plt.close(ax.figure)
    surface = plot.plot_3d(empty)
    assert len(surface.collections) == 0
    plt.close(surface.figure)


def ellipsoid_checkpoint(path, eps=0.08, axes=(0.5, 0.3, 0.3), box=(0.8, 1.2)):
    """Write a checkpoint of the harmonics m = 0, 2, 4 of a tanh ellipsoid long along x
    (no solve), centred at Zb / 2."""
    from pfmembrane.kernels import initial
    from pfmembrane.kernels.harmonics import Harmonics
    from pfmembrane.kernels.nodes import uniform
    xy = uniform(box, 1500)
    h = Harmonics(4, 2)
    phi = initial.harmonic_coefficients(
        xy - [0.0, 0.5 * box[1]], lambda p: initial.ellipsoid_phi(p, axes, eps), h, 0.02)
    attrs = {"energy": 9.0, "area": 1.5, "volume": 0.3, "moment": 0.0, "eps": eps,
             "k": 1.0, "c0": 0.0, "gamma": 0.8, "nu_area": 0.0, "nu_volume": 0.0,
             "converged": 1, "wall_time": 1.0, "box": box, "cutoff": 1e-6,
             "harmonics": h.m, "harmonics_highest": 4, "dihedral": 2}
    checkpoint.write(path, xy, phi, attrs, sample=field3d.sample)
    return checkpoint.read(path)


def test_a_checkpoint_with_harmonics_is_drawn_as_its_3d_surface(tmp_path):
    ckpt = ellipsoid_checkpoint(tmp_path / "ellipsoid.h5")
    ax = plot.plot_3d(ckpt)
    ax.figure.canvas.draw()  # a 3D collection has its 2D paths once projected
    (drawn,) = ax.collections
    surface = field3d.level_surface(ckpt)
    assert len(drawn.get_paths()) == len(surface.triangles) > 1000
    # the surface is the ellipsoid's, not a surface of revolution: semi-axes 0.5 along x,
    # 0.3 along y and z, to within the marching step (eps / 2) and the fit
    x, y, z = surface.vertices.T
    half = [np.ptp(c) / 2 for c in (x, y, z)]
    assert np.allclose(half, (0.5, 0.3, 0.3), atol=0.02), half
    plt.close(ax.figure)


def test_cli_draws_a_checkpoint_with_harmonics_in_3d_only(tmp_path, run_plot):
    ellipsoid_checkpoint(tmp_path / "ellipsoid.h5")
    result = run_plot(tmp_path / "ellipsoid.h5", "--what", "field,3d", "--dpi", 60)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == [str(tmp_path / "ellipsoid_3d.png")]
    assert "has harmonics: no 'field' figure" in result.stderr
    assert_picture(tmp_path / "ellipsoid_3d.png", min_bytes=5_000)
