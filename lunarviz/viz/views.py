"""PyVista scene compositions: lit and earthshine-lit Moon, ray paths, BRDF maps, numbers.

``build_plotter`` returns a :class:`pyvista.Plotter` (offscreen or not) for one of
:data:`VIEWS`; the desktop viewer (:mod:`lunarviz.viz.viewer`) and the screenshots share it.

Panels of the ``composite`` view:

1. the Moon seen from the detector, coloured by its total radiance toward the detector on
   one logarithmic grey scale: the sunlit crescent and the faint earthshine side as an eye
   (or a camera) would see them, with the numbers beside it;
2. the earthshine radiance alone, on its own logarithmic scale;
3. light paths Sun → (Earth →) Moon → detector in a schematic layout (real distances are
   compressed and the bodies enlarged: at real scale they would be invisible dots);
4. the patch BRDF map: reflectance factor π·BRDF for sunlight at each facet.

The ``maps`` view adds the sunlit fraction of every facet: the shadows that a non-convex
Moon (craters, topography) casts on itself, and the Earth's shadow in an eclipse.

The ``surfaces`` view shows the Moon's albedo parameter per facet (a lunar albedo
map) seen from the detector, and the Earth seen from the Moon: its per-facet albedo (land,
ocean, clouds) and its radiance toward the Moon, with the earthshine-weighted albedo.
"""

from __future__ import annotations

import numpy as np
import pyvista as pv

from lunarviz.errors import unknown_choice
from lunarviz.methods.tracer.facet_result import FacetResult
from lunarviz.outputs.writers import StagedFiles, check_output_path, numbered_paths, png_bytes, write_bytes_atomic
from lunarviz.viz.meshio import facet_polydata
from lunarviz.viz.render_window import choose_render_window
from lunarviz.viz.view_data import ComputeView, ViewData

VIEWS = ("composite", "moon", "rays", "maps", "surfaces")
#: the explorer's four panels: the composite's, without its numbers (the explorer prints them beside)
EXPLORE_VIEW = "explore"
#: its Moon panels' zoom (they are nearly square: room for the colour bar beside the disc)
EXPLORE_ZOOM = 0.8
#: Dynamic range of the logarithmic colour scales (max / floor).
LOG_RANGE = 1e7
#: Colour levels of every colour map: 256 levels over the six decades of a log scale drew false
#: contour rings across the disc
N_COLORS = 2048


def numbers_text(n: dict) -> str:
    def f(v, fmt):
        return "n/a" if v is None or not np.isfinite(v) else format(v, fmt)
    head = [f"{n['time_utc']}   observer {n['observer']}"] if "time_utc" in n else []
    return "\n".join(head + [
        f"phase theta = {n['theta_deg']:.1f} deg   alpha = {n['alpha_deg']:.2f} deg   beta = {n['beta_deg']:.2f} deg",
        f"BRDF: {n['brdf']}    method: {n['method']}",
        f"moonshine  E = {f(n['moonshine_W_m2'], '.4e')} W/m^2",
        f"earthshine E = {f(n['earthshine_W_m2'], '.4e')} W/m^2  (point Earth {f(n['point_source_earthshine_W_m2'], '.4e')})",
        f"earthshine / moonshine = {f(n['ratio'], '.4e')}",
        f"apparent albedo p* = {f(n['apparent_albedo'], '.4f')}  (point-source inversion {f(n['apparent_albedo_point_inversion'], '.4f')})",
        f"albedo of the Earth's lit face, as earthshine weights it = {f(n.get('earth_visible_lit_albedo'), '.4f')}",
        f"rays traced: {n['rays']:,}    {n['error_note']}",
    ])


def _log_field(values, floor=None):
    """Values for a log colour scale: zeros (dark, unseen) become NaN; limits robust."""
    v = np.asarray(values, dtype=float)
    pos = v[v > 0]
    if pos.size == 0:
        return np.full_like(v, np.nan), (1e-30, 1.0)
    vmax = float(pos.max())
    lo = float(np.percentile(pos, 1.0)) if floor is None else floor
    lo = max(lo, vmax / LOG_RANGE)
    return np.where(v > 0, np.maximum(v, lo), np.nan), (lo, vmax)


def _linear_field(values, mask):
    v = np.where(mask, np.asarray(values, dtype=float), np.nan)
    ok = v[np.isfinite(v)]
    if ok.size == 0:
        return v, (0.0, 1.0)
    return v, (float(np.percentile(ok, 1.0)), float(np.percentile(ok, 99.0)))


def _ashen_floor(poly):
    """Lower colour limit of the radiance panels: one that keeps the earthshine ('ashen light')
    side visible, except where the sunlit part fills most (3/4) of the visible disc (near full Moon):
    there the ashen light is a sliver the eye cannot see beside it, and a scale stretched over
    seven decades for it would paint the sunlit disc one flat white; the floor is then 1e-3 of
    the brightest facet, so the sunlit disc keeps its shading."""
    cd = poly.cell_data
    es = np.asarray(cd["earthshine_radiance_W_m2_sr"])
    total = np.asarray(cd["moonshine_radiance_W_m2_sr"]) + es
    seen = np.asarray(cd["emission_deg"]) < 90
    lit = seen & (np.asarray(cd["incidence_deg"]) < 90)
    pos = es[es > 0]
    floor = float(np.percentile(pos, 1.0)) * 0.1 if pos.size else None
    if seen.any() and lit.sum() > 0.75 * seen.sum() and total.max() > 0:
        floor = max(floor or 0.0, float(total.max()) * 1e-3)
    return floor


def _grey_map():
    """Black to light grey (not white: the brightest facets keep a visible gradient)."""
    from matplotlib.colors import ListedColormap
    g = np.linspace(0.0, 0.92, N_COLORS)
    return ListedColormap(np.stack([g, g, g], axis=1), name="lunar_grey")


def _lunar_north(fr: FacetResult) -> np.ndarray:
    """The Moon's north pole in scene axes: +x in the θ scene, MOON_ME's z on dates."""
    rot = fr.info.get("moon_rotation_body_to_scene")
    return np.asarray(rot, dtype=float)[:, 2] if rot is not None else np.array([1.0, 0.0, 0.0])


def _sun_direction(fr: FacetResult) -> np.ndarray:
    """Unit vector from the Moon's centre toward the Sun, scene axes."""
    d = np.array(fr.info["sun_m"]) - np.array(fr.info["moon_centre_m"])
    return d / np.linalg.norm(d)


def _in_image_plane(v, view):
    """``v`` projected onto the plane normal to ``view``, unit length (None if along ``view``)."""
    w = np.asarray(v, dtype=float) - np.dot(v, view) * view
    n = np.linalg.norm(w)
    return w / n if n > 1e-6 else None


def _sky_north(fr: FacetResult) -> np.ndarray:
    """The sky's north in scene axes (SceneGeometry.sky_north): ICRF z on dates, +x in the θ scene."""
    return np.array([0.0, 0.0, 1.0]) if "time_utc" in fr.info else np.array([1.0, 0.0, 0.0])


def panel_camera(fr: FacetResult, zoom=1.0, up=None):
    """The Moon panels' camera: focal point, viewing direction (from the observer toward the Moon),
    up (unit vectors, scene axes) and the parallel scale (half the panel's height) [m]; the
    Moon's centre at the origin. Oriented like the sky and like ``lunarviz image``: the sky's
    north up and east to the left (:func:`_sky_north`; lunar north where the sky's lies along
    the line of sight)."""
    moon = np.array(fr.info["moon_centre_m"])
    det = np.array(fr.info["detector_m"])
    R = float(np.max(np.linalg.norm(fr.vertices, axis=1)))
    view = (det - moon) / np.linalg.norm(det - moon)
    if up is None:
        up = _in_image_plane(_sky_north(fr), view)
        if up is None:
            up = _in_image_plane(_lunar_north(fr), view)
    up = np.asarray(up, dtype=float)
    if abs(np.dot(up, view)) > 0.99:
        up = np.array([0.0, 1.0, 0.0])
    up = _in_image_plane(up, view)
    # the Moon a little left of centre, so the colour bar on the right never covers its limb
    right = np.cross(view, up)
    right = right / np.linalg.norm(right)
    focal = -right * 0.25 * R / zoom  # ``right`` = cross(view, up) points to the image's left
    return focal, -view, up, 1.2 * R / zoom


def _camera_from_detector(pl, fr: FacetResult, zoom=1.0, up=None, key=True):
    """Look at the Moon from the detector (parallel projection; :func:`panel_camera`). ``key`` draws
    the orientation key: arrows toward the Sun and to lunar north, and where the view is from."""
    focal, look, up, scale = panel_camera(fr, zoom, up)
    R = float(np.max(np.linalg.norm(fr.vertices, axis=1)))
    pl.camera_position = [tuple(focal - look * 8 * R), tuple(focal), tuple(up)]
    pl.enable_parallel_projection()
    pl.camera.parallel_scale = scale
    if key:
        _orientation_key(pl, fr, -look, up, R)


def _orientation_key(pl, fr: FacetResult, view, up, R):
    """Arrows at the disc's lower left: toward the Sun (projected) and to lunar north; the
    observer is named in the panel's bottom line."""
    screen_up = np.asarray(up, dtype=float)
    screen_right = -np.cross(view, screen_up)  # the image's right
    base = (-0.92 * screen_right - 1.0 * screen_up) * R + view * 1.2 * R  # (labels inside the panel)
    for vec, label, color in ((_sun_direction(fr), "Sun", "gold"), (_lunar_north(fr), "lunar N", "white")):
        d = _in_image_plane(vec, view)
        if d is None:  # along the line of sight: say so instead of drawing a dot
            label = f"{label} (along the line of sight)"
            d = screen_up
        # an arrow that points left or down starts further right or up, so it stays in the panel
        start = base + 0.34 * R * (max(0.0, -float(np.dot(d, screen_right))) * screen_right
                                   + max(0.0, -float(np.dot(d, screen_up))) * screen_up)
        pl.add_mesh(pv.Arrow(start=start, direction=d, scale=0.32 * R, tip_length=0.3, tip_radius=0.12,
                             shaft_radius=0.04), color=color, lighting=False)
        pl.add_point_labels([start + d * 0.42 * R], [label], font_size=10, text_color=color, shape=None,
                            show_points=False, always_visible=True)
    where = "the detector at the Earth's centre" if "time_utc" not in fr.info else "the observer"
    pl.add_text(f"seen from {where}; north up, east left", font_size=10, position="lower_left", color="white")
    if not (fr.totals.get("moonshine_W_m2") or fr.totals.get("earthshine_W_m2")):
        why = "hidden from the observer" if fr.info.get("moon_occulted") else "dark: no light reaches the detector"
        pl.add_text(f"the Moon is {why}", font_size=9, position=(0.02, 0.9), viewport=True, color="orange")


def _cells_to_points(mesh, names):
    """Point data: at each vertex the mean of its facets' finite values (NaN facets, dark or
    unseen, do not blank their neighbours' vertices); NaN where no adjacent facet has one."""
    faces = mesh.faces.reshape(-1, 4)[:, 1:]
    out = pv.PolyData(mesh.points.copy(), mesh.faces.copy())
    for name in names:
        v = np.asarray(mesh.cell_data[name], dtype=float)
        ok = np.isfinite(v)
        total = np.zeros(mesh.n_points)
        count = np.zeros(mesh.n_points)
        for c in range(3):
            np.add.at(total, faces[ok, c], v[ok])
            np.add.at(count, faces[ok, c], 1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            pts = np.where(count > 0, total / np.maximum(count, 1.0), np.nan)
        for _ in range(2):  # vertices with only NaN facets take their finite neighbours' mean
            ok_p = np.isfinite(pts)
            hole = ~ok_p
            if not hole.any():
                break
            total = np.zeros(mesh.n_points)
            count = np.zeros(mesh.n_points)
            for a in range(3):
                for b in range(3):
                    if a != b:
                        src, dst = faces[:, a], faces[:, b]
                        use = ok_p[src] & hole[dst]
                        np.add.at(total, dst[use], pts[src[use]])
                        np.add.at(count, dst[use], 1.0)
            fill = hole & (count > 0)
            pts[fill] = total[fill] / count[fill]
        out.point_data[name] = pts
    return out


def _moon_panel(pl, poly, field, title, cmap, log=True, clim=None, bar_fmt="%.1e", mask=None, floor=None,
                smooth=True, sun_dir=None, dark_field=None):
    """One Moon panel: ``field`` on the mesh, with a colour bar titled ``title`` (keep it short:
    two lines of ≤ 12 characters fit the bar at 1024×768).

    ``smooth`` interpolates the facet values across facets; with ``sun_dir`` (unit vector toward
    the Sun, the mesh's axes) the mesh is also cut along the terminator's plane, so the
    terminator is the smooth great circle it is, not the facets' sawtooth: the sunlit half shows
    ``field``, the night half ``dark_field`` (its earthshine; ``None``: nothing). A degenerate
    range (one value) gets a single-label bar instead of four equal labels."""
    mesh = poly.copy()
    if log:
        vals, lim = _log_field(mesh.cell_data[field], floor)
    else:
        vals, lim = _linear_field(mesh.cell_data[field], np.ones(mesh.n_cells, bool) if mask is None else mask)
    lim = tuple(clim or lim)
    n_labels = 4
    if not (lim[1] > lim[0] * (1 + 1e-9) + 1e-300):  # one value: widen a little, label once
        centre = lim[0]
        lim = (centre * 0.999, centre * 1.001) if centre else (-0.5, 0.5)
        n_labels = 1
    scalars = field + "_shown"
    mesh.cell_data[scalars] = vals
    if dark_field is not None:
        dark = np.asarray(mesh.cell_data[dark_field], dtype=float)
        mesh.cell_data["_dark_shown"] = np.where(dark > 0, np.maximum(dark, lim[0]), np.nan) if log else dark
    parts = [mesh]
    if smooth:
        mesh = _cells_to_points(mesh, [n for n in (scalars, "_dark_shown") if n in mesh.cell_data])
        parts = [mesh]
        if sun_dir is not None:
            lit = mesh.clip(normal=tuple(sun_dir), origin=(0.0, 0.0, 0.0), invert=False)
            night = mesh.clip(normal=tuple(sun_dir), origin=(0.0, 0.0, 0.0), invert=True)
            night.point_data[scalars] = night.point_data["_dark_shown"] if dark_field is not None else \
                np.full(night.n_points, np.nan)
            parts = [p for p in (lit, night) if p.n_points]
    bar = {"title": title + "\n", "fmt": bar_fmt, "n_labels": n_labels, "vertical": True, "color": "white",
           "position_x": 0.80, "position_y": 0.06, "height": 0.66, "width": 0.045,
           "title_font_size": 12, "label_font_size": 11}
    has_values = bool(np.isfinite(vals).any())  # nothing to scale (a hidden Moon): no colour bar
    for k, part in enumerate(parts):
        pl.add_mesh(part, scalars=scalars, cmap=cmap, log_scale=log, clim=lim, nan_color=(0.12, 0.12, 0.14),
                    show_edges=False, lighting=False, interpolate_before_map=True, n_colors=N_COLORS,
                    show_scalar_bar=k == 0 and has_values, scalar_bar_args=bar)
    return mesh


def facet_centroids(fr: FacetResult) -> np.ndarray:
    """The lunar facets' centroids in scene axes about the Moon's centre [m] (as the panels draw them)."""
    c = np.asarray(fr.vertices, dtype=float)[np.asarray(fr.faces)].mean(axis=1)
    rot = fr.info.get("moon_rotation_body_to_scene")
    return c if rot is None else c @ np.asarray(rot, dtype=float).T


def _mark_facet(pl, fr: FacetResult, picked: int | None) -> None:
    """A red ring about the picked facet on a Moon panel (in front of the disc)."""
    if picked is None:
        return
    c = facet_centroids(fr)[picked]
    R = float(np.linalg.norm(c))
    pl.add_mesh(pv.Sphere(radius=0.045 * R, center=c * 1.02), color="red", lighting=False)


def facet_brdf_dome(fr: FacetResult, picked: int, model):
    """The picked facet's own BRDF map: π·BRDF for sunlight (point data ``pi*BRDF``) over the
    hemisphere of view directions about its normal (the sphere's, as the exact shading takes it),
    at its own albedo parameter; and the unit directions from it toward the Sun, the detector and
    the Earth (scene axes). Zero where the Sun is below its horizon."""
    from lunarviz.geometry.scene_geometry import half_angle_sin_cos
    c = facet_centroids(fr)[picked]
    n = c / np.linalg.norm(c)
    here = np.array(fr.info["moon_centre_m"]) + c
    towards = {name: (np.array(fr.info[key]) - here) / np.linalg.norm(np.array(fr.info[key]) - here)
               for name, key in (("Sun", "sun_m"), ("detector", "detector_m"), ("Earth", "earth_m"))}
    dome = pv.Sphere(radius=1.0, theta_resolution=96, phi_resolution=48).clip(normal=tuple(-n), origin=(0, 0, 0))
    w = np.asarray(dome.points, dtype=float)
    w /= np.linalg.norm(w, axis=1)[:, None]
    s = towards["Sun"]
    mu0 = max(float(n @ s), 0.0)
    sh, ch = half_angle_sin_cos(np.broadcast_to(s, w.shape), w)
    alb = fr.cell_data.get("albedo_parameter")
    a = None if alb is None else np.full(len(w), float(alb[picked]))
    f = np.pi * np.asarray(model.brdf(np.full(len(w), mu0), np.clip(w @ n, 0.0, 1.0), sh, ch, albedo=a), dtype=float) \
        if mu0 > 0 else np.zeros(len(w))
    dome.point_data["pi*BRDF"] = np.where(np.isfinite(f), f, 0.0)
    return dome, n, towards


def _facet_brdf_panel(pl, fr: FacetResult, picked: int, model) -> None:
    """:func:`facet_brdf_dome` drawn, with arrows toward the Sun, the detector and the Earth."""
    dome, n, towards = facet_brdf_dome(fr, picked, model)
    lit = bool(np.any(dome.point_data["pi*BRDF"] > 0))  # (unlit: zeros on a 0-1 bar, not a bar of one value)
    pl.add_mesh(dome, scalars="pi*BRDF", cmap="viridis", clim=None if lit else (0.0, 1.0),
                lighting=False, n_colors=N_COLORS,
                scalar_bar_args={"title": "pi*BRDF\n", "vertical": True, "color": "white", "position_x": 0.82,
                                 "position_y": 0.06, "height": 0.66, "width": 0.045, "fmt": "%.3f",
                                 "title_font_size": 12, "label_font_size": 11})
    for (name, v), colour, at in zip(towards.items(), ("gold", "white", "deepskyblue"), (1.55, 1.55, 1.8)):
        pl.add_mesh(pv.Arrow(start=(0, 0, 0), direction=v, scale=1.45, tip_length=0.12, tip_radius=0.03,
                             shaft_radius=0.012), color=colour, lighting=False)
        pl.add_point_labels([v * at], [name], font_size=10, text_color=colour, shape=None, show_points=False,
                            always_visible=True)
    cos_i = float(n @ towards["Sun"])
    i = np.degrees(np.arccos(np.clip(cos_i, -1, 1)))
    pl.add_text(f"facet {picked}: pi*BRDF over view directions\n(sunlight at i = {i:.1f} deg"
                + (", below its horizon)" if cos_i <= 0 else ")"), font_size=11, position="upper_left", color="white")
    side = np.cross(n, towards["detector"])
    side = side / np.linalg.norm(side) if np.linalg.norm(side) > 1e-9 else np.cross(n, [1.0, 0.0, 0.0])
    eye = n + 0.7 * side / np.linalg.norm(side)  # oblique (35° off the normal): the dome's map and the arrows
    up = n - (n @ eye) / (eye @ eye) * eye
    focal = 0.35 * n
    pl.camera_position = [tuple(focal + 5 * eye), tuple(focal), tuple(up)]
    pl.enable_parallel_projection()
    pl.camera.parallel_scale = 1.6


def _frame_panel(pl, frame: dict) -> None:
    """An instrument's frame in counts [ADU] (row 0 at the bottom: north up, east left, as
    ``lunarviz image``), on a square-root grey scale, with the measurement pipeline's patches
    outlined: earthlit (blue), sunlit (orange), sky (green)."""
    if frame.get("counts") is None:  # the pipeline refused the task before imaging it: say why
        pl.add_text(f"{frame['name']}: no frame\n" + "\n".join(
            frame["note"][i:i + 44] for i in range(0, len(frame["note"]), 44)), font_size=10,
            position="upper_left", color="orange")
        return
    counts = np.asarray(frame["counts"], dtype=float)
    H, W = counts.shape
    grid = pv.ImageData(dimensions=(W + 1, H + 1, 1))
    grid.cell_data["counts"] = counts.ravel()  # (x fastest: a row of the frame at a time, row 0 at y = 0)
    lo, hi = float(counts.min()), float(counts.max())
    pl.add_mesh(grid, scalars="counts", cmap="gray", clim=(lo, hi if hi > lo else lo + 1), lighting=False,
                scalar_bar_args={"title": "counts\nADU\n", "vertical": True, "color": "white", "position_x": 0.82,
                                 "position_y": 0.06, "height": 0.66, "width": 0.045, "fmt": "%.0f",
                                 "title_font_size": 12, "label_font_size": 11})
    patches = frame.get("patches")
    if patches is not None:
        for name, colour in (("earthlit", "deepskyblue"), ("sunlit", "orange"), ("sky", "limegreen")):
            mask = pv.ImageData(dimensions=(W + 1, H + 1, 1))
            mask.cell_data["in"] = np.asarray(getattr(patches, name), dtype=float).ravel()
            edge = mask.cell_data_to_point_data().contour([0.5], scalars="in")
            if edge.n_points:
                pl.add_mesh(edge.translate((0, 0, 1)), color=colour, line_width=2, lighting=False)
    pl.add_text(f"{frame['name']}: frame in counts, {frame['exposure_s']:g} s\npatches: earthlit (blue), sunlit "
                "(orange), sky (green)" if patches is not None else f"{frame['name']}: frame in counts "
                f"({frame['note'][:48]})", font_size=10, position="upper_left", color="white")
    pl.camera_position = [(W / 2, H / 2, 3 * max(W, H)), (W / 2, H / 2, 0.0), (0.0, 1.0, 0.0)]
    pl.enable_parallel_projection()
    pl.camera.parallel_scale = 0.62 * H


def _ray_panel(pl, data: ViewData, text: str | None = None, picked: int | None = None):
    """Light paths, schematic: directions as seen from the Earth are kept, distances are not
    (the Moon at 2 units, the Sun at 3.4: the triangle stays legible), bodies enlarged. Seen
    from the normal of the Sun-Earth-Moon plane, drawn in the right part of the panel; the
    numbers (``text``) go on the left, and the bottom stays free for the viewer's controls."""
    fr = data.facets
    moon = np.array(fr.info["moon_centre_m"])
    sun = np.array(fr.info["sun_m"])
    det = np.array(fr.info["detector_m"])
    earth = np.zeros(3)

    def place(centre, dist):
        d = np.linalg.norm(centre)
        return centre / d * dist if d > 0 else centre
    C = {"sun": place(sun, 3.4), "earth": earth, "moon": place(moon, 2.0)}
    Rs = {"sun": 0.42, "earth": 0.3, "moon": 0.14}
    Rw = {"sun": 6.957e8, "earth": 6.378e6, "moon": 1.738e6}
    Cw = {"sun": sun, "earth": earth, "moon": moon}
    colors = {"sun": "gold", "earth": "royalblue", "moon": "lightgray"}
    normal = np.cross(sun, moon)
    normal = normal / np.linalg.norm(normal) if np.linalg.norm(normal) > 0 else np.array([1.0, 0.0, 0.0])
    up = C["sun"] - C["moon"]
    up = up - np.dot(up, normal) * normal
    up = up / np.linalg.norm(up) if np.linalg.norm(up) > 0 else np.array([0.0, 0.0, 1.0])
    for b in C:
        pl.add_mesh(pv.Sphere(radius=Rs[b], center=C[b], theta_resolution=32, phi_resolution=32),
                    color=colors[b], smooth_shading=True)
        side = -1.0 if b == "moon" else 1.0  # the Moon's label below it, clear of the light paths
        pl.add_point_labels([C[b] + side * up * Rs[b] * 2.2], [b.capitalize()], font_size=11,
                            text_color="white", shape=None, show_points=False, always_visible=True)

    def snap(p, body):
        return C[body] + Rs[body] * (p - Cw[body]) / Rw[body]

    bodies = {"moonshine": ["sun", "moon", "det"], "earthshine": ["sun", "earth", "moon", "det"]}
    for path, color in (("moonshine", "orange"), ("earthshine", "deepskyblue")):
        for line in data.rays.get(path, []):
            pts = []
            for p, b in zip(line, bodies[path]):
                pts.append(snap(p, "earth") if b == "det" else snap(p, b))
            pl.add_mesh(pv.lines_from_points(np.array(pts)), color=color, line_width=2)
    pl.add_point_labels([snap(det, "earth")], ["detector"], font_size=9, text_color="white",
                        point_color="red", point_size=8, shape=None)
    legend = "light paths (schematic)\norange: Sun>Moon>detector\nblue: Sun>Earth>Moon>detector"
    if picked is not None:  # the picked facet's own paths: from the Sun's and the Earth's centres, to the detector
        p = snap(facet_centroids(fr)[picked] + moon, "moon")
        for a, b in ((C["sun"], p), (C["earth"], p), (p, snap(det, "earth"))):
            pl.add_mesh(pv.lines_from_points(np.array([a, b])), color="red", line_width=3)
        pl.add_mesh(pv.Sphere(radius=0.035, center=p), color="red")
        legend += f"\nred: facet {picked}'s paths"
    pl.add_text(legend if text is None else text + "\n\n" + legend, font_size=10 if text is None else 9,
                position="upper_left", color="white")
    pts = np.array(list(C.values()))
    centre = 0.5 * (pts.min(0) + pts.max(0))
    span = float(np.max(np.linalg.norm(pts - centre, axis=1))) + 0.6
    right = np.cross(up, normal)
    if text is None:  # the schematic fills the panel, under the legend
        focal = centre + up * span * 0.1
        scale = span * 1.0
    else:  # the schematic in the right ~55 % of the panel (the numbers on the left), above the controls
        focal = centre - right * span * 0.7 - up * span * 0.2
        scale = span * 1.3
    pl.camera_position = [tuple(focal + normal * 20 * span), tuple(focal), tuple(up)]
    pl.enable_parallel_projection()
    pl.camera.parallel_scale = scale


SHAPES = {"composite": (2, 2), "maps": (2, 2), "moon": (1, 1), "rays": (1, 1), "surfaces": (2, 2), "explore": (2, 2)}


def _earth_panel(pl, fr: FacetResult, field: str, title: str, cmap: str, log: bool):
    """The Earth seen from the Moon's centre, coloured by its facet ``field``."""
    v, f, cd = fr.bodies["earth"]
    mesh = pv.PolyData(np.asarray(v), np.hstack([np.full((len(f), 1), 3), f]).astype(np.int64))
    vals = np.asarray(cd[field], dtype=float)
    if log:
        vals, lim = _log_field(vals)
    else:
        lim = (float(np.min(vals)), float(np.max(vals)))
        if lim[1] <= lim[0]:
            lim = (lim[0] - 0.05, lim[0] + 0.05)
    mesh.cell_data["shown"] = vals
    bar = dict(title=title + "\n", color="white", fmt="%.2e" if log else "%.2f", vertical=True, position_x=0.84,
               position_y=0.08, height=0.68, width=0.06, title_font_size=12, label_font_size=10)
    pl.add_mesh(mesh, scalars="shown", cmap=cmap, log_scale=log, clim=lim, nan_color=(0.05, 0.05, 0.08),
                lighting=False, scalar_bar_args=bar)
    moon = np.array(fr.info["moon_centre_m"]) - np.array(fr.info["earth_m"])
    view = moon / np.linalg.norm(moon)
    up = _in_image_plane(_sky_north(fr), view)  # (the sky's north up, as every picture)
    up = up if up is not None else _in_image_plane(np.array([0.0, 1.0, 0.0]), view)
    R = float(np.max(np.linalg.norm(v, axis=1)))
    focal = -np.cross(view, up) / np.linalg.norm(np.cross(view, up)) * 0.15 * R  # (the disc left of the colour bar)
    pl.camera_position = [tuple(focal + view * 8 * R), tuple(focal), tuple(up)]
    pl.enable_parallel_projection()
    pl.camera.parallel_scale = 1.3 * R


def build_plotter(data: ViewData, view: str = "composite", size=(1600, 900), off_screen=True,
                  picked: int | None = None, brdf_model=None, frame: dict | None = None,
                  lower: str = "brdf") -> pv.Plotter:
    """A plotter showing ``view`` of ``data`` (``picked``: a facet marked); call ``show()`` or ``screenshot()``."""
    if view not in VIEWS + (EXPLORE_VIEW,):
        raise unknown_choice("view", view, VIEWS)
    choose_render_window()
    pl = pv.Plotter(off_screen=off_screen, window_size=size, shape=SHAPES[view])
    populate(pl, data, view, picked, brdf_model, frame, lower)
    return pl


def populate(pl: pv.Plotter, data: ViewData, view: str = "composite", picked: int | None = None,
             brdf_model=None, frame: dict | None = None, lower: str = "brdf") -> pv.Plotter:
    """Draw ``view`` of ``data`` into an existing plotter of shape ``SHAPES[view]``; ``picked``: a
    lunar facet marked on the Moon panels, its paths drawn in the schematic (composite views) and,
    in the explorer's view with its ``brdf_model``, its own BRDF map in place of the Moon's; ``frame``
    (the explorer's view): an instrument's frame in counts with its patches, there instead; else
    ``lower`` (the explorer's view): ``brdf`` the Moon's BRDF map, ``earth`` the Earth seen from the
    Moon (its radiance toward the Moon)."""
    fr = data.facets
    poly = facet_polydata(fr)
    rot = fr.info.get("moon_rotation_body_to_scene")
    if rot is not None:  # the Moon's body frame (MOON_ME on dates) → scene axes, where the camera is
        poly.points = np.asarray(poly.points, dtype=float) @ np.asarray(rot, dtype=float).T
    sun_dir = _sun_direction(fr)
    cd = poly.cell_data
    poly.cell_data["total_radiance"] = cd["moonshine_radiance_W_m2_sr"] + cd["earthshine_radiance_W_m2_sr"]
    text = numbers_text(data.numbers)
    if view == "moon":
        pl.subplot(0, 0)
        pl.set_background("black")
        _moon_panel(pl, poly, "total_radiance", "radiance\nW m-2 sr-1", _grey_map(), floor=_ashen_floor(poly),
                    sun_dir=sun_dir, dark_field="earthshine_radiance_W_m2_sr")
        pl.add_text(text, font_size=9, position="upper_left", color="white")
        _camera_from_detector(pl, fr)
        return pl
    if view == "rays":
        pl.subplot(0, 0)
        pl.set_background("black")
        _ray_panel(pl, data)
        return pl
    if view == "surfaces":
        pl.subplot(0, 0)
        pl.set_background("black")
        seen = poly.cell_data["emission_deg"] < 90
        _moon_panel(pl, poly, "albedo_parameter", "albedo\nor w", "gray", log=False, bar_fmt="%.3f", mask=seen)
        pl.add_text("Moon: albedo parameter per facet", font_size=11, position="upper_left", color="white")
        _camera_from_detector(pl, fr)
        pl.subplot(0, 1)
        pl.set_background("black")
        _earth_panel(pl, fr, "albedo", "albedo", "Blues_r", log=False)
        pl.add_text("Earth from the Moon: albedo per facet", font_size=11, position="upper_left", color="white")
        pl.subplot(1, 0)
        pl.set_background("black")
        _earth_panel(pl, fr, "radiance_toward_moon_W_m2_sr", "radiance\nW m-2 sr-1", "inferno", log=True)
        pl.add_text("Earth from the Moon: radiance toward the Moon", font_size=11, position="upper_left",
                    color="white")
        pl.subplot(1, 1)
        pl.set_background("black")
        pl.add_text(text, font_size=9, position="upper_left", color="white")
        return pl
    if view == "maps":
        panels = [("incidence_deg", "i [deg]", "cividis", (0, 90), "incidence i of sunlight"),  # (sequential: 0 and 90 differ)
                  ("emission_deg", "e [deg]", "cividis", (0, 90), "emission e toward the detector"),
                  ("solar_lit_fraction", "sunlit\nfraction", "gray", (0, 1), "sunlit fraction (shadows)"),
                  ("reflectance_factor", "pi*BRDF", "viridis", None, "reflectance factor pi*BRDF for sunlight")]
        for k, (field, title, cmap, clim, long_title) in enumerate(panels):
            pl.subplot(k // 2, k % 2)
            pl.set_background("black")
            seen = poly.cell_data["emission_deg"] < 90
            lit = seen & (poly.cell_data["incidence_deg"] < 90)
            _moon_panel(pl, poly, field, title, cmap, log=False, clim=clim, bar_fmt="%.3g",
                        mask=seen if field == "emission_deg" else lit,
                        sun_dir=None if field == "emission_deg" else sun_dir)
            pl.add_text("Moon: " + long_title, font_size=11, position="upper_left", color="white")
            _camera_from_detector(pl, fr)
        return pl
    return _composite(pl, data, view, poly, text, picked, brdf_model, frame, lower)


def _composite(pl, data: ViewData, view: str, poly, text: str, picked, brdf_model, frame, lower):
    """The composite view's four panels (and the explorer's, :data:`EXPLORE_VIEW`): see :func:`populate`."""
    fr = data.facets
    sun_dir = _sun_direction(fr)
    zoom = EXPLORE_ZOOM if view == EXPLORE_VIEW else 1.0
    pl.subplot(0, 0)
    pl.set_background("black")
    _moon_panel(pl, poly, "total_radiance", "radiance\nW m-2 sr-1", _grey_map(), floor=_ashen_floor(poly),
                sun_dir=sun_dir, dark_field="earthshine_radiance_W_m2_sr")
    pl.add_text("Moon: radiance toward the detector (log)", font_size=11, position="upper_left", color="white")
    _camera_from_detector(pl, fr, zoom=zoom)
    _mark_facet(pl, fr, picked)
    pl.subplot(0, 1)
    pl.set_background("black")
    _moon_panel(pl, poly, "earthshine_radiance_W_m2_sr", "earthshine\nW m-2 sr-1", "cividis")
    pl.add_text("Moon: earthshine only (own log scale)", font_size=11, position="upper_left", color="white")
    _camera_from_detector(pl, fr, zoom=zoom)
    _mark_facet(pl, fr, picked)
    pl.subplot(1, 0)
    pl.set_background("black")
    _ray_panel(pl, data, None if view == EXPLORE_VIEW else text, picked)
    pl.subplot(1, 1)
    pl.set_background("black")
    if view == EXPLORE_VIEW and picked is not None and brdf_model is not None:  # the picked facet's own map
        _facet_brdf_panel(pl, fr, picked, brdf_model)
        return pl
    if view == EXPLORE_VIEW and frame is not None:  # the instrument's frame
        _frame_panel(pl, frame)
        return pl
    if view == EXPLORE_VIEW and lower == "earth":  # what the Earth sends toward the Moon
        # (a bar title of its own: PyVista shares one bar between panels whose titles agree)
        _earth_panel(pl, fr, "radiance_toward_moon_W_m2_sr", "Earth\nW m-2 sr-1", "inferno", log=True)
        pl.add_text("Earth seen from the Moon: its radiance toward it (log)", font_size=11, position="upper_left",
                    color="white")
        return pl
    lit = (poly.cell_data["emission_deg"] < 90) & (poly.cell_data["incidence_deg"] < 90)
    _moon_panel(pl, poly, "reflectance_factor", "pi*BRDF\nsunlight", "viridis", log=False,
                bar_fmt="%.3f", mask=lit, sun_dir=sun_dir)
    pl.add_text(f"Moon: BRDF map pi*BRDF ({data.numbers['brdf']}, sunlight)", font_size=11, position="upper_left",
                color="white")
    _camera_from_detector(pl, fr, zoom=zoom)
    _mark_facet(pl, fr, picked)
    return pl


def render_image(data: ViewData, view="composite", size=(1600, 900), out=None) -> np.ndarray:
    """One offscreen picture (RGB, height × width × 3) of what ``data`` holds; also written as PNG
    to ``out`` (atomically) when given."""
    pl = build_plotter(data, view, size, off_screen=True)
    pl.render()
    img = np.asarray(pl.screenshot(return_img=True))
    pl.close()
    if out is not None:
        write_bytes_atomic(out, png_bytes(img))
    return img


def render_frames(compute: ComputeView, phases, brdf, out, view="composite", size=(1600, 900), gif=None,
                  progress=False) -> list:
    """Render one PNG per phase or date (``out`` itself for one, else ``out_000.png`` …), each from
    ``compute(key, brdf)``."""
    from pathlib import Path

    targets = numbered_paths(out, len(phases))
    for target in targets + ([Path(gif)] if gif else []):
        check_output_path(target, (target.suffix.lower(),))  # a folder in the way: refused before work
    files: list = []
    it = phases
    if progress and len(phases) > 1:
        from tqdm import tqdm
        it = tqdm(phases, desc="render", unit="frame", leave=False)
    images = []
    with StagedFiles() as staged:  # every frame (and the GIF) or none
        for k, th in enumerate(it):
            images.append(render_image(compute(th, brdf), view=view, size=size, out=staged.stage(targets[k])))
            files.append(targets[k])
        if gif:
            import io

            from PIL import Image
            frames = [Image.fromarray(np.asarray(img)[..., :3]).convert("P", palette=Image.Palette.ADAPTIVE)
                      for img in images]
            buf = io.BytesIO()
            frames[0].save(buf, format="GIF", save_all=True, append_images=frames[1:], duration=250, loop=0)
            write_bytes_atomic(staged.stage(gif), buf.getvalue())
            files.append(Path(gif))
    return files
