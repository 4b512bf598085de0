# %% [markdown]
# # Three IMU grades on one mission, navigated with pyins
#
# A notebook in script form (cells marked `# %%`; open it in Jupyter with jupytext, VS Code or
# Spyder, or run it: `python examples/python/three_grades.py [--short] [-o FIGURE]`).
#
# 1. `imu_emu.simulate` turns the native mission `examples/mission.toml` into the records of a
#    navigation-grade (LN-200), a tactical-grade (STIM300) and a MEMS (ADIS16488) IMU, with the
#    truth trajectory (`pose=True`).
# 2. pyins' loosely coupled filter (`pyins.filters.run_feedback_filter`, an error-state EKF)
#    navigates each with GNSS positions at 1 Hz, then through a GNSS outage.
# 3. The horizontal position error against time since the outage began is plotted per grade.
#
# Needs: `pip install ./python python-ins matplotlib` (see docs/python.md).

# %%
import argparse
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from pyins import filters, inertial_sensor, measurements, strapdown, transform

import imu_emu

HERE = pathlib.Path(__file__).resolve().parent
MISSION = HERE.parent / "mission.toml"
GRADES = {"navigation (LN-200)": "ln200", "tactical (STIM300)": "stim300",
          "MEMS (ADIS16488)": "adis16488"}
# The filter's sensor models, from each template's turn-on bias and white noise (1σ, SI):
# gyro bias (rad/s), ARW (rad/√s), accel bias (m/s²), VRW (m/s/√s).
DEG_H, G = np.deg2rad(1) / 3600, 9.80665
FILTER_MODEL = {
    "ln200": (1 * DEG_H, np.deg2rad(0.07) / 60, 50e-6 * G, 50e-6 * G),
    "stim300": (4 * DEG_H, np.deg2rad(0.15) / 60, 0.75e-3 * G, 0.07 / 60),
    "adis16488": (0.2 * 3600 * DEG_H, np.deg2rad(0.3) / 60, 16e-3 * G, 0.029 / 60),
}

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--short", action="store_true",
                    help="a reduced run for tests: 100 s of the mission at 50 Hz, a 30 s outage")
parser.add_argument("-o", "--output", default="three_grades.png", help="figure file")
args = parser.parse_args([] if "ipykernel" in sys.modules else None)

RATE = 50.0 if args.short else 100.0          # IMU rate (Hz)
DURATION = 100.0 if args.short else 400.0     # mission span simulated (s)
OUTAGE = (70.0, 100.0) if args.short else (250.0, 370.0)    # GNSS outage (s)
GNSS_SD = 1.0                                 # GNSS position noise (m, 1σ)
SEED = 1

# %% [markdown]
# ## Simulate: records, truth and the trajectory
# One call per grade; the same seed gives the same records as
# `imu-emu generate --motion-def examples/mission.toml --imu NAME --rate 100 --duration 400
# --seed 1`.

# %%
runs = {label: imu_emu.simulate(motion_def=MISSION, imu=name, rate=RATE, duration=DURATION,
                                 seed=SEED, pose=True)
        for label, name in GRADES.items()}
pose = next(iter(runs.values())).pose
truth = pd.DataFrame({"lat": pose["lat"], "lon": pose["lon"], "alt": pose["h"],
                      "VN": pose["v_ned"][:, 0], "VE": pose["v_ned"][:, 1],
                      "VD": pose["v_ned"][:, 2], "roll": pose["rpy"][:, 0],
                      "pitch": pose["rpy"][:, 1], "heading": pose["rpy"][:, 2]},
                     index=pd.Index(pose["t"], name="time"))
print(f"{len(truth)} truth samples, {len(runs)} IMUs")

# %% [markdown]
# ## GNSS positions (1 Hz, 1 m noise) with an outage

# %%
rng = np.random.default_rng(SEED)
fix_t = np.arange(truth.index[0], truth.index[-1] + 1e-9, 1.0)
fix_t = fix_t[(fix_t < OUTAGE[0]) | (fix_t > OUTAGE[1])]
fixes = truth.loc[truth.index.intersection(fix_t), ["lat", "lon", "alt"]].copy()
fixes[["lat", "lon", "alt"]] = transform.perturb_lla(
    fixes.values, GNSS_SD * rng.standard_normal((len(fixes), 3)))
gnss = measurements.Position(fixes, GNSS_SD)

# %% [markdown]
# ## Navigate each grade with the loosely coupled filter
# Our records are raw increments (no coning/sculling compensation): pyins' increment
# sensor type applies its own, after a duplicated "before" sample as its convention asks.

# %%
def navigate(name, r):
    gb, arw, ab, vrw = FILTER_MODEL[name]
    rows = np.vstack([r.records.rows[:1], r.records.rows])
    t = np.r_[truth.index[0], r.records.t]
    imu = pd.DataFrame(np.hstack([rows[:, 7:10], rows[:, 10:13]]), index=t,
                       columns=["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"])
    increments = strapdown.compute_increments_from_imu(imu, "increment")
    result = filters.run_feedback_filter(
        truth.iloc[0], 1.0, 0.1, 0.05, 0.5, increments,
        gyro_model=inertial_sensor.EstimationModel(bias_sd=gb, noise=arw),
        accel_model=inertial_sensor.EstimationModel(bias_sd=ab, noise=vrw),
        measurements=[gnss], time_step=1.0)
    err = transform.compute_state_difference(result.trajectory, truth)
    return np.hypot(err["north"], err["east"])


horizontal = {label: navigate(GRADES[label], r) for label, r in runs.items()}

# %% [markdown]
# ## Error growth in the outage

# %%
fig, ax = plt.subplots(figsize=(8, 4.5))
for label, e in horizontal.items():
    inside = (e.index >= OUTAGE[0]) & (e.index <= OUTAGE[1])
    ax.semilogy(e.index[inside] - OUTAGE[0], np.maximum(e[inside], 1e-3), label=label)
ax.set_xlabel("time since GNSS lost (s)")
ax.set_ylabel("horizontal position error (m)")
ax.set_title(f"examples/mission.toml, GNSS outage {OUTAGE[0]:.0f}–{OUTAGE[1]:.0f} s, seed {SEED}")
ax.grid(True, which="both", alpha=0.3)
ax.legend()
fig.tight_layout()
fig.savefig(args.output, dpi=110)
for label, e in horizontal.items():
    end = e[e.index <= OUTAGE[1]].iloc[-1]
    print(f"{label:24s} horizontal error at the outage end: {end:9.3f} m")
print(f"figure: {args.output}")
