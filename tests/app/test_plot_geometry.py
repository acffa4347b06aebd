"""Mode shapes on the measurement geometry (ami_xr.plot.geometry) and their place in the report
(issue 12 item 5): what is drawn (panels, titles, axis labels with units, deformed = coordinate
+ scale * shape), the animated GIF (frames, size) and the error without coordinates."""

from __future__ import annotations

import io

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.app.report import report
from ami_xr.core.modal import phase_normalised
from ami_xr.errors import AmiXrValueError
from ami_xr.plot.geometry import animate_mode_shape, plot_mode_shapes

pytest.importorskip("matplotlib")
Image = pytest.importorskip("PIL.Image")

N_POINT = 5
X = np.linspace(0.0, 2.0, N_POINT)  # a beam-like line of points, m
Y = np.array([0.0, 0.3, 0.0, 0.3, 0.0])  # a zigzag in the x-y plane, m


@pytest.fixture(scope="module")
def beam_modes() -> xr.Dataset:
    """The simulator's 5-point random chain, identified, its points on a line (point_x, m)."""
    g, _ = ami_xr.simulate.random_system(
        n_points=N_POINT, n_modes=5, noise=0.02, seed=3, n_frequencies=1024
    )
    g = g.assign_coords({names.POINT_X: (names.POINT, X, {names.ATTR_UNITS: "m"})})
    return ami_xr.identify(g)


@pytest.fixture(scope="module")
def plate_modes(beam_modes) -> xr.Dataset:
    """The same modes with the points in the x-y plane."""
    return beam_modes.assign_coords({names.POINT_Y: (names.POINT, Y, {names.ATTR_UNITS: "m"})})


def _shapes(ds):
    return np.real(ds[names.MODE_VECTOR_NORMALISED].transpose(names.POINT, names.MODE).values)


def _deformed(ax):
    (line,) = [ln for ln in ax.lines if ln.get_label().startswith("deformed")]
    return line


def _frequency_hz(ds):
    return ds[names.NATURAL_FREQUENCY].values


def test_one_panel_per_mode_titled_with_frequency_and_damping(beam_modes):
    fig = plot_mode_shapes(beam_modes)
    n_mode = beam_modes.sizes[names.MODE]
    assert len(fig.axes) == n_mode
    for ax, fn, zeta, label in zip(
        fig.axes,
        _frequency_hz(beam_modes),
        beam_modes[names.DAMPING_RATIO].values,
        beam_modes[names.MODE].values,
        strict=True,
    ):
        title = ax.get_title(loc="left")
        assert title.startswith(f"mode {label}: ")
        assert f"{fn:.4g} Hz" in title
        assert f"ζ {100 * zeta:.3g} %" in title
        assert {t.get_text() for t in ax.get_legend().get_texts()} >= {"undeformed"}


def test_modes_selects_panels(beam_modes):
    fig = plot_mode_shapes(beam_modes, modes=[2, 4])
    assert [ax.get_title(loc="left").split(":")[0] for ax in fig.axes] == ["mode 2", "mode 4"]
    with pytest.raises(AmiXrValueError, match=r"modes \[99\] are not among the modes"):
        plot_mode_shapes(beam_modes, modes=[99])


def test_line_geometry_draws_deflection_against_x(beam_modes):
    scale = 0.7
    fig = plot_mode_shapes(beam_modes, scale=scale)
    shapes = _shapes(beam_modes)
    for k, ax in enumerate(fig.axes):
        assert ax.get_xlabel() == "point_x [m]"
        assert "shape [-]" in ax.get_ylabel()
        line = _deformed(ax)
        np.testing.assert_allclose(line.get_xdata(), X)
        np.testing.assert_allclose(line.get_ydata(), scale * shapes[:, k])
        assert np.max(np.abs(shapes[:, k])) == pytest.approx(1.0)  # phase-normalised
        (under,) = [ln for ln in ax.lines if ln.get_label() == "undeformed"]
        np.testing.assert_allclose(under.get_ydata(), 0.0)


def test_units_of_the_coordinates_label_the_axes(beam_modes):
    in_mm = beam_modes.assign_coords(
        {names.POINT_X: (names.POINT, 1000 * X, {names.ATTR_UNITS: "mm"})}
    )
    assert plot_mode_shapes(in_mm, modes=[1]).axes[0].get_xlabel() == "point_x [mm]"


def test_planar_geometry_deformed_in_plane(plate_modes):
    scale = 0.05
    fig = plot_mode_shapes(plate_modes, direction="y", scale=scale)
    shapes = _shapes(plate_modes)
    for k, ax in enumerate(fig.axes):
        assert (ax.get_xlabel(), ax.get_ylabel()) == ("point_x [m]", "point_y [m]")
        line = _deformed(ax)
        np.testing.assert_allclose(line.get_xdata(), X)
        np.testing.assert_allclose(line.get_ydata(), Y + scale * shapes[:, k])


def test_planar_geometry_deformed_out_of_plane_along_z(plate_modes):
    scale = 0.2
    fig = plot_mode_shapes(plate_modes, scale=scale)  # direction z by default
    shapes = _shapes(plate_modes)
    for k, ax in enumerate(fig.axes):
        assert ax.name == "3d"
        assert (ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel()) == (
            "point_x [m]",
            "point_y [m]",
            "point_z [m]",
        )
        xs, ys, zs = _deformed(ax).get_data_3d()
        np.testing.assert_allclose(xs, X)
        np.testing.assert_allclose(ys, Y)
        np.testing.assert_allclose(zs, scale * shapes[:, k])


def test_default_scale_is_a_fraction_of_the_geometry(plate_modes):
    ax = plot_mode_shapes(plate_modes, modes=[1]).axes[0]
    zs = _deformed(ax).get_data_3d()[2]
    np.testing.assert_allclose(zs, 0.15 * np.ptp(X) * _shapes(plate_modes)[:, 0])


def test_lines_join_the_given_point_pairs(plate_modes):
    pairs = [(0, 1), (1, 2), (0, 4)]
    ax = plot_mode_shapes(plate_modes, modes=[1], direction="y", lines=pairs).axes[0]
    assert len(ax.lines) == 2 + 2 * len(pairs)  # all points (both states) + each segment
    assert _deformed(ax).get_linestyle() == "None"  # points are not joined in their order
    with pytest.raises(AmiXrValueError, match=r"lines: points \[7\] are not among"):
        plot_mode_shapes(plate_modes, lines=[(0, 7)])


def test_without_coordinates_the_error_names_them(beam_modes):
    bare = beam_modes.drop_vars(names.POINT_X)
    with pytest.raises(AmiXrValueError, match=r"no point coordinates.*point_x, point_y, point_z"):
        plot_mode_shapes(bare)
    with pytest.raises(AmiXrValueError, match=r"point_x, point_y, point_z"):
        animate_mode_shape(bare, 1)


def test_other_bad_input_is_named(beam_modes, plate_modes):
    frf_only = beam_modes[[names.FRF]]
    with pytest.raises(AmiXrValueError, match="mode_vector"):
        plot_mode_shapes(frf_only)
    with pytest.raises(AmiXrValueError, match="direction must be 'x', 'y' or 'z'"):
        plot_mode_shapes(plate_modes, direction="up")
    with pytest.raises(AmiXrValueError, match="scale must be"):
        plot_mode_shapes(beam_modes, scale=np.nan)


def test_shapes_from_mode_vector_when_not_normalised(beam_modes):
    older = beam_modes.drop_vars(names.MODE_VECTOR_NORMALISED)
    ax = plot_mode_shapes(older, modes=[3], scale=1.0).axes[0]
    phi = older[names.MODE_VECTOR].transpose(names.POINT, names.MODE).values
    np.testing.assert_allclose(
        _deformed(ax).get_ydata(), phase_normalised(phi, unit=True)[:, 2].real
    )


def test_figure_saved_atomically_and_by_the_accessor(tmp_path, beam_modes):
    path = tmp_path / "shapes.png"
    fig = beam_modes.ami.plot_mode_shapes(modes=[1], path=path)
    assert len(fig.axes) == 1
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shapes.png"]
    assert ami_xr.plot_mode_shapes is plot_mode_shapes


# --- animation -------------------------------------------------------------------------------


@pytest.mark.parametrize("frames", [16, 5])
def test_gif_has_the_frames_asked_for(tmp_path, beam_modes, frames):
    path = tmp_path / "mode1.gif"
    data = animate_mode_shape(beam_modes, 1, path, frames=frames)
    assert data[:6] == b"GIF89a"
    assert path.read_bytes() == data
    with Image.open(path) as im:
        assert im.n_frames == frames
        assert max(im.size) <= 400
        assert im.info.get("loop") == 0
    assert len(data) <= 300_000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mode1.gif"]  # no temporary left


def test_gif_of_a_3d_view_to_a_buffer(plate_modes):
    buf = io.BytesIO()
    data = animate_mode_shape(plate_modes, 2, buf, frames=8)
    assert buf.getvalue() == data
    assert data[:6] == b"GIF89a" and len(data) <= 300_000
    with Image.open(io.BytesIO(data)) as im:
        assert im.n_frames == 8
        assert im.size == (400, 300)


def test_gif_bad_arguments(beam_modes):
    with pytest.raises(AmiXrValueError, match="frames must be an integer from 2 to 120"):
        animate_mode_shape(beam_modes, 1, frames=1)
    with pytest.raises(AmiXrValueError, match=r"modes \['x'\] are not among"):
        animate_mode_shape(beam_modes, "x")


# --- report ----------------------------------------------------------------------------------


def test_report_embeds_the_shape_figure_and_the_gif_of_the_mode(tmp_path, beam_modes):
    """The fast version of the next test: one mode, the shape figures only."""
    one = beam_modes.isel({names.MODE: [0]})
    index = report(one, tmp_path / "rep", figures=("mode_shapes",))
    page = index.read_text()
    assert page.count("data:image/gif;base64,R0lGODlh") == 1  # base64 of b"GIF89a"
    assert "alt='mode_shapes.png'" in page and "Not produced" not in page
    label = one[names.MODE].values[0]
    assert (index.parent / f"mode_shape_{label}.gif").read_bytes()[:6] == b"GIF89a"


@pytest.mark.slow
def test_report_embeds_shapes_and_one_gif_per_mode(tmp_path, beam_modes):
    index = report(beam_modes, tmp_path / "rep")
    page = index.read_text()
    n_mode = beam_modes.sizes[names.MODE]
    assert page.count("data:image/gif;base64,R0lGODlh") == n_mode  # base64 of b"GIF89a"
    assert "alt='mode_shapes.png'" in page
    folder = index.parent
    assert (folder / "mode_shapes.png").exists()
    for label in beam_modes[names.MODE].values:
        assert (folder / f"mode_shape_{label}.gif").read_bytes()[:6] == b"GIF89a"
    assert "mode_vectors.png" in page  # the bars stay
    assert "Not produced" not in page


def test_report_without_coordinates_keeps_the_bars_only(tmp_path, beam_modes):
    bare = beam_modes.drop_vars(names.POINT_X)
    page = report(bare, tmp_path / "rep").read_text()
    assert "data:image/gif" not in page
    assert "mode_shapes" not in page
    assert "alt='mode_vectors.png'" in page
    assert not list((tmp_path / "rep").glob("*.gif"))
    # asked for explicitly, it is listed as not produced, naming the coordinates
    page = report(bare, tmp_path / "rep2", figures=("mode_shapes",)).read_text()
    assert "Not produced" in page and "point_x, point_y, point_z" in page
    assert "data:image/gif" not in page
