"""A low-Earth-orbit earthshine instrument on real dates, from Python.

    python examples/leo_real_date.py            # every 20 min for one day (72 times, ~1 min)
    LUNARVIZ_SMOKE=1 python examples/leo_real_date.py   # three times (CI)

A 550 km polar circular orbit (``orbit:ALT_KM,INC_DEG,RAAN_DEG,ARGLAT_DEG``; use ``tle:FILE``
for a real spacecraft) looks at the Moon on 2026-06-09, five days after first quarter. The
ray tracer hides the Moon whenever the Earth is in the way (``moon_occulted``). Writes
``leo.nc`` (NetCDF, open it with ``xarray.open_dataset``) and ``leo.png``.
"""

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import lunarviz  # noqa: E402

smoke = bool(os.environ.get("LUNARVIZ_SMOKE"))
scene = lunarviz.Scene(time_range="2026-06-09T00:00,2026-06-09T00:40,20min" if smoke
                       else "2026-06-09T00:00,2026-06-09T23:40,20min",
                       observer="orbit:550,97.6,0,0", brdfs=("dhg",))
ds = lunarviz.sweep(scene, method="raytrace")
ds.to_netcdf("leo.nc", engine="h5netcdf")

visible = ds.moon_occulted == 0
print(f"{int(visible.sum())} of {ds.sizes['time']} times see the Moon; "
      f"phase angle {float(ds.phase_angle.min()):.1f}-{float(ds.phase_angle.max()):.1f} deg")
print("earthshine/moonshine where visible:",
      ds.ratio_earthshine_moonshine.sel(brdf="dhg").where(visible).values)

fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
ds.moonshine.sel(brdf="dhg").plot(ax=ax[0], marker=".")
ds.earthshine.sel(brdf="dhg").plot(ax=ax[1], marker=".")
ax[0].set_title("550 km polar orbit, 2026-06-09 (0 = Moon behind the Earth)")
fig.tight_layout()
fig.savefig("leo.png", dpi=100)
