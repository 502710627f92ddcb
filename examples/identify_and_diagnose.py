#!/usr/bin/env python3
"""Identify and diagnose a pneumatic muscle model from Python, step by step.

    PYTHONPATH=build/python python3 examples/identify_and_diagnose.py OUT_DIR [--data rec.csv] [--short]

Without --data it records the plant emulator (the physics plant) in open loop first. Writes PNG figures
(matplotlib, Agg: fit.png, ladder.png, final.png) and the final model (model.json) into OUT_DIR. --short: a short record and a small diagnosis."""
import argparse
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import pamc  # noqa: E402

# %% The record: read one, or excite the emulator open loop (as `pamc emulate` does) with Table 1's input u0.
parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("out_dir")
parser.add_argument("--data", help="measurement CSV (t,u,y[,load,...]); default: record the emulator")
parser.add_argument("--short", action="store_true", help="12 s record, one diagnosis round on two candidates")
args = parser.parse_args()
os.makedirs(args.out_dir, exist_ok=True)


def emulate(seconds):
    plant, u_of = pamc.Plant(), pamc.Trajectory("sine:0.1:0.2:2.9")
    t = np.arange(round(seconds / plant.Ts)) * plant.Ts
    u = u_of(t)
    plant.reset(u[0])
    y = np.array([(plant.step(uk), plant.measure())[1] for uk in u])
    return pamc.Measurement(t, u, y, source="emulator")


data = pamc.read_csv(args.data) if args.data else emulate(12.0 if args.short else 40.0)
print(f"{data.source}: {len(data)} samples, Ts = {data.Ts:g} s")

# %% Identify the Bouc-Wen reference model and see where it fails.
model, report = pamc.fit(data, method="lm")
print(f"fitted {model.describe()}: RMSE {report['rmse']:.4g} in {report['seconds']:.1f} s")
for name, value in model.parameters.items():
    print(f"  {name:12s} {value:.6g}")
cmp = pamc.compare(model, data)
print(f"compare: RMSE {cmp['rmse']:.4g}, max |e| {cmp['max_abs']:.4g}, fit {cmp['fit_pct']:.1f} %")

fig, ax = plt.subplots(3, 1, figsize=(8, 8))
ax[0].plot(data.t, data.y, label="measured")
ax[0].plot(data.t, cmp["y_model"], label="model", lw=0.8)
ax[0].set(xlabel="t [s]", ylabel="y [mm]", title="reference model on the record")
ax[0].legend()
ax[1].plot(data.t, cmp["residual"])
ax[1].set(xlabel="t [s]", ylabel="y - model [mm]", title="residual")
ax[2].plot(data.u, data.y, label="measured")
ax[2].plot(data.u, cmp["y_model"], label="model", lw=0.8)
ax[2].set(xlabel="u [V]", ylabel="y [mm]", title="hysteresis loop")
ax[2].legend()
fig.tight_layout()
fig.savefig(os.path.join(args.out_dir, "fit.png"), dpi=90)

# %% Diagnose: which physical effect is missing, added one at a time while the validated error falls.
settings = dict(max_effects=1, candidates=["saturation", "pressure_lag"], probes=False) if args.short else {}
result = pamc.diagnose(data, **settings)
print(f"diagnose ({result['validation']}): {result['verdict']}")
ladder = result["ladder"]
names = ["reference"] + ["+ " + " + ".join(r["effects"]) for r in ladder[1:]]
fig, ax = plt.subplots(figsize=(8, 4))
x = np.arange(len(ladder))
ax.bar(x - 0.2, [r["rmse_train"] for r in ladder], 0.4, label="training")
ax.bar(x + 0.2, [r["rmse_val"] for r in ladder], 0.4, label="validation")
ax.set_xticks(x, names, rotation=15, ha="right")
ax.set(ylabel="RMSE [mm]", title="diagnosis ladder")
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(args.out_dir, "ladder.png"), dpi=90)

# %% The final model against the reference model on the whole record.
final = result["final_model"]
final_cmp = pamc.compare(final, data)
print(f"final model {final.describe()}: RMSE {final_cmp['rmse']:.4g} on the whole record")
fig, ax = plt.subplots(figsize=(8, 4))
ax.plot(data.t, cmp["residual"], label=f"reference model ({cmp['rmse']:.3g} mm rms)")
ax.plot(data.t, final_cmp["residual"], label=f"{final.describe()} ({final_cmp['rmse']:.3g} mm rms)")
ax.set(xlabel="t [s]", ylabel="y - model [mm]", title="residual before and after the diagnosis")
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(args.out_dir, "final.png"), dpi=90)
final.save(os.path.join(args.out_dir, "model.json"))
print(f"fit.png, ladder.png, final.png and model.json in {args.out_dir}/")
