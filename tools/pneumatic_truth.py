#!/usr/bin/env python3
"""The physics plant's own parameters (`pamc plant`, rig mode) written as a pamc model of the Bouc-Wen core
(rho 1: a straight gain) and one balance effect - how far the structure itself reaches on the plant's
records, before any search (docs/MODELING.md, "The pressure's own dynamics").

  tools/pneumatic_truth.py [--pamc BIN] [--plant FILE] [--effect pneumatic_balance|muscle_balance]
                           [--coulomb-in-friction | --coulomb-as-guide [--guide-speed [VC]]] [--valve-lag]
                           --out MODEL.json

The balance is divided by the plant's linear stiffness (rubber + load spring); the Tondu-Lopez map gives
a1, a2; the braid's Dahl friction zmax, zp and delta; the regulator's gauge pressure, atmosphere and supply
in the balance's units give the pressure's levels; the ISO 6358 conductance at the supply over the
volume at zero contraction its rate; the braid's volume growth at zero contraction over that volume its
swell. The plant's payload Coulomb friction (tanh of the velocity) has no exact place in the balance:
--coulomb-in-friction adds its level to zmax, --coulomb-as-guide puts it on pneumatic_balance's guide
element (zc, with a pre-sliding travel dc of 0.01 mm, a choice: the tanh has a velocity width, not a
travel); with --guide-speed the guide's friction builds up with the sliding speed as the tanh does (vc, the
speed of half its level: VC mm/s, or without VC the tanh's velocity width, where the two laws' slopes at
rest agree) from a pre-sliding travel of 0.001 mm, the box's least. --valve-lag gives pneumatic_balance
the regulator's valve-opening time constant.
"""
import argparse
import json
import math
import subprocess
import sys

TANH_WIDTH = -1.0  # --guide-speed without a value: the plant's tanh width


def plant_config(pamc, path):
    if path:
        with open(path) as f:
            return json.load(f)
    return json.loads(subprocess.run([pamc, "plant"], stdout=subprocess.PIPE, check=True, text=True).stdout)


def balance_of(pc, coulomb_in_friction):
    m, g, l = pc["muscle"], pc["regulator"], pc["payload"]
    area = math.pi * (0.5e-3 * m["diameter_mm"]) ** 2
    th = math.radians(m["braid_angle_deg"])
    cos2 = math.cos(th) ** 2
    a, b = 3 * cos2 / (1 - cos2), 1 / (1 - cos2)
    length = m["length_mm"] * m.get("tondu_k", 1.0) ** -1
    kn = kn_of(pc)  # N/mm
    per_bar = area * (a - b) * 1e5 / kn  # the pressure's static displacement per bar [mm]
    weight = l["mass_kg"] * l["gravity_m_per_s2"] + l["spring_preload_N"]
    wn = math.sqrt(kn * 1e3 / l["mass_kg"])
    zmax = m["hysteresis_N"] + (l["coulomb_N"] if coulomb_in_friction else 0.0)
    balance = {"fn": wn / (2 * math.pi), "zeta": l["viscous_N_s_per_m"] / (2 * l["mass_kg"] * wn), "zmax": zmax / kn,
               "delta": m["hysteresis_travel_mm"], "w": weight / kn, "a1": -2 * a / (length * (a - b)),
               "a2": a / (length * length * (a - b)), "zp": m["hysteresis_N_per_bar"] / (per_bar * kn), "spread": 1.0,
               "lo": pc["stroke"]["min_mm"], "hi": pc["stroke"]["max_mm"]}
    core = {"k": g["setpoint_bar_per_V"] * per_bar, "rho": 1.0, "alpha": 1.0, "beta": 0.35, "gamma": 0.25}
    core["b"] = g["setpoint_offset_V"] * core["k"] - balance["w"]
    return balance, core, per_bar, area * (a - b)


def pressure_of(pc, per_bar, dvol_dy, coulomb_as_guide, valve_lag, guide_speed):
    g, m = pc["regulator"], pc["muscle"]
    vol0 = math.pi * (0.5e-3 * m["diameter_mm"]) ** 2 * m["length_mm"] * 1e-3 + g["dead_volume_cm3"] * 1e-6
    p_sup = (g["supply_bar"] + g["atmosphere_bar"]) * 1e5
    rt = 287.05 * g["temperature_K"]
    rate = g["polytropic_index"] * rt * g["conductance_dm3_per_s_bar"] * 1e-8 * 1.185 * p_sup / vol0  # Pa/s
    return {"rate": rate / 1e5 * per_bar, "vent": 1.0, "band": g["band_bar"] * per_bar,
            "span": g["atmosphere_bar"] * per_bar, "supply": g["supply_bar"] * per_bar, "b": g["critical_ratio"],
            "swell": dvol_dy * 1e-3 / vol0, "n": g["polytropic_index"],
            "lag": g["tau_s"] if valve_lag else 0.0,
            "zc": pc["payload"]["coulomb_N"] / kn_of(pc) if coulomb_as_guide else 0.0,
            "dc": 0.001 if guide_speed is not None else 0.01,
            "vc": 0.0 if guide_speed is None else
                  pc["payload"]["coulomb_velocity_mm_per_s"] if guide_speed == TANH_WIDTH else guide_speed}


def kn_of(pc):
    return pc["muscle"]["rubber_N_per_mm"] + pc["payload"]["spring_N_per_mm"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pamc", default="build/src/pamc")
    ap.add_argument("--plant", help="plant file (JSON); default: `pamc plant`")
    ap.add_argument("--effect", default="pneumatic_balance", choices=["pneumatic_balance", "muscle_balance"])
    how = ap.add_mutually_exclusive_group()
    how.add_argument("--coulomb-in-friction", action="store_true")
    how.add_argument("--coulomb-as-guide", action="store_true")
    ap.add_argument("--guide-speed", nargs="?", type=float, const=TANH_WIDTH, default=None, metavar="VC")
    ap.add_argument("--valve-lag", action="store_true")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    if a.guide_speed is not None and not a.coulomb_as_guide:
        sys.exit("pneumatic_truth: --guide-speed needs --coulomb-as-guide")
    if a.guide_speed is not None and a.guide_speed != TANH_WIDTH and not a.guide_speed >= 0.0:
        sys.exit("pneumatic_truth: --guide-speed VC must be a speed >= 0 [mm/s]")
    pc = plant_config(a.pamc, a.plant)
    if pc.get("mode") != "rig":
        sys.exit("pneumatic_truth: the plant is not in rig mode")
    balance, core, per_bar, dvol_dy = balance_of(pc, a.coulomb_in_friction)
    params = dict(balance)
    if a.effect == "pneumatic_balance":
        params.update(pressure_of(pc, per_bar, dvol_dy, a.coulomb_as_guide, a.valve_lag, a.guide_speed))
    model = {"format": "pamc-model/1", "core": core, "output_form": "aligned",
             "effects": [{"name": a.effect, "params": params}]}
    with open(a.out, "w") as f:
        json.dump(model, f, indent=1)


if __name__ == "__main__":
    main()
