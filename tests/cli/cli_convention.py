#!/usr/bin/env python3
"""The command-line convention of docs/CLI.md, checked over every command's --help (subcommands of
subcommands too), and the old spellings: each still accepted, with a one-line notice naming the new one.
Prints one line per failure and a summary line; exit 1 on any failure."""
import re
import subprocess
import sys

pamc = sys.argv[1]
fails = []

# Spellings the convention replaced: none may be listed by a --help.
REPLACED = {"--report", "--work", "--config", "--rt", "--forms", "--lags", "--soak", "--faults", "--sdo-guards", "--no-grid"}
# Options that select from a list keep their names; every other list of values to sweep ends in -grid.
SELECTORS = {"--only", "--only-axes", "--candidates", "--effects", "--eds"}
# The old spellings (until 0.3.0): the command line, and the new spelling the notice must name.
OLD = [
    (["experiments", "--out", "x"], "experiments --out-dir"),
    (["compare", "m.json", "d.csv", "--report", "x"], "compare --out-dir"),
    (["diagnose", "d.csv", "--report", "x"], "diagnose --out-dir"),
    (["monitor", "--log", "x.log"], "monitor --replay"),
    (["plant", "--config", "p.json"], "plant --plant"),
    (["controller", "--rt"], "controller --realtime"),
    (["emulator", "--rt"], "emulator --realtime"),
    (["rig", "--duration", "1"], "rig run"),
    (["rig", "--rt"], "rig run --realtime"),
    (["rig", "run", "--rt"], "rig run --realtime"),
    (["rig", "--faults", "--only", "bus-off"], "rig faults"),
    (["rig", "--sdo-guards"], "rig guards"),
    (["rig", "--soak", "1"], "rig soak --hours"),
    (["robustness", "--no-grid"], "robustness --no-pairs"),
]


def helptext(cmd):
    h = subprocess.run([pamc] + cmd + ["--help"], capture_output=True, text=True)
    if h.returncode != 0:
        fails.append(f"pamc {' '.join(cmd)} --help exits {h.returncode}")
    return h.stdout


def subcommands(text):
    if "Subcommands:" not in text:
        return []
    return re.findall(r"^  ([a-z][a-z-]*)\s{2,}", text.split("Subcommands:")[1], re.M)


def options(text):
    """{--name: its help text} of the Options block (continuation lines joined)."""
    block = text.split("Options:")[1].split("Subcommands:")[0] if "Options:" in text else ""
    out, name = {}, None
    for line in block.splitlines():
        m = re.match(r"^  (?:-\w,)?(--[a-z0-9-]+)(?:,--[a-z0-9-]+)*(.*)$", line)
        if m:
            name = m.group(1)
            out[name] = m.group(2)
        elif name and line.startswith("    "):
            out[name] += " " + line.strip()
    return out


def check_option(where, name, help_):
    h = help_.lower()
    if name in REPLACED:
        fails.append(f"{where}: {name} is a spelling the convention replaced")
    if name == "--out" and re.search(r"\b(folder|directory)\b", h):
        fails.append(f"{where}: --out names a folder (--out-dir is a folder's option)")
    if name == "--out-dir" and not re.search(r"\b(folder|directory)\b", h):
        fails.append(f"{where}: --out-dir does not say it is a folder")
    if name != "--out-dir" and re.search(r"\b(output folder|folder for|directory for)\b", h):
        fails.append(f"{where}: {name} is an output folder: --out-dir")
    if name == "--log" and not re.search(r"\bwrite", h):
        fails.append(f"{where}: --log must write a log (--replay reads one)")
    if name != "--plant" and re.search(r"\bplant (file|emulator config)\b", h):
        fails.append(f"{where}: {name} reads a plant file: --plant")
    if name.endswith("-grid") != ("comma list" in h and name not in SELECTORS):
        fails.append(f"{where}: {name}: a list to sweep ends in -grid, and only such a list")
    if name == "--json" and "json" not in h:
        fails.append(f"{where}: --json does not say it writes JSON")


def walk():
    shared = {}  # --cpu / --priority: one meaning wherever they appear
    commands = [[c] for c in subcommands(helptext([]))]
    if len(commands) < 10:
        fails.append(f"pamc --help lists only {commands}")
    checked = 0
    for cmd in commands:
        text = helptext(cmd)
        where = "pamc " + " ".join(cmd)
        commands += [cmd + [s] for s in subcommands(text)]
        for name, help_ in options(text).items():
            check_option(where, name, help_)
            checked += 1
            if name in ("--cpu", "--priority"):
                shared.setdefault(name, {})[help_.strip()] = where
    for name, texts in shared.items():
        if len(texts) > 1:
            fails.append(f"{name} means different things: {sorted(texts.values())}")
    rig = helptext(["rig"])
    if set(subcommands(rig)) != {"run", "faults", "soak", "guards"}:
        fails.append(f"pamc rig's subcommands are {subcommands(rig)}, not run, faults, soak, guards")
    if set(options(rig)) != {"--help"}:
        fails.append(f"pamc rig lists options of its own: {sorted(options(rig))}")
    return len(commands), checked


def old_spellings():
    for args, new in OLD:
        r = subprocess.run([pamc, "--parse-only"] + args, capture_output=True, text=True)
        notes = [l for l in r.stderr.splitlines() if "is now" in l]
        if r.returncode != 0:
            fails.append(f"old spelling pamc {' '.join(args)}: exit {r.returncode}")
        elif len(notes) != 1 or f"'{new}'" not in notes[0] or "0.3.0" not in notes[0]:
            fails.append(f"old spelling pamc {' '.join(args)}: no one-line notice naming '{new}' ({r.stderr.strip()})")


n, checked = walk()
old_spellings()
for f in fails:
    print("FAIL:", f)
print(f"{n} commands, {checked} options, {len(OLD)} old spellings checked, {len(fails)} failures")
sys.exit(1 if fails else 0)
