#!/usr/bin/env python3
"""One place per fact: the valve's command range, the bus delay and the NMT start-up object are written
once (src/control/actuation.hpp, canopen/nmt_master.hpp); the code of the nodes, the controllers, the
command line and the rig derives from them. Greps src/nodes, src/control, src/app and src/rig (comments
and strings left out) for their literals. Parameter bounds of effects and probes are not such facts.
Prints one line per hit and a summary line; exit 1 on any hit."""
import pathlib
import re
import sys

src = pathlib.Path(sys.argv[1])
DIRS = ["src/nodes", "src/control", "src/app", "src/rig"]
DEFINITIONS = {"src/control/actuation.hpp", "canopen/nmt_master.hpp"}
# (what, pattern on code without comments and strings)
FACTS = [
    ("the valve range as a literal", re.compile(r"(?<![\w.])-\s*5(\.0*)?(?![\w.])")),
    ("the valve range as a literal", re.compile(r"\b(u_min|u_max|safe_u|last_u)\w*\s*=\s*[-+]?\d")),
    ("the bus delay as a literal", re.compile(r"\bdelay_cycles\w*\s*=\s*\d")),
    ("a definition of the valve range or bus delay",
     re.compile(r"\b(kValveFullScale_V|kValveMid_V|kCommandMin|kCommandMax|kBusDelayCycles)\s*=\s*(?!\s|control::)")),
    ("0x1F80 as a literal (canopen::kObjStartup)", re.compile(r"\b0x1[fF]80\b")),
]


def code_only(text):
    text = re.sub(r"/\*.*?\*/", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    return re.sub(r'"(\\.|[^"\\\n])*"', '""', text)


hits, files = 0, 0
for d in DIRS:
    for p in sorted((src / d).rglob("*")):
        if p.suffix not in (".hpp", ".cpp", ".inc") or str(p.relative_to(src)) in DEFINITIONS:
            continue
        files += 1
        for n, line in enumerate(code_only(p.read_text()).splitlines(), 1):
            for what, pat in FACTS:
                if pat.search(line):
                    print(f"FAIL: {p.relative_to(src)}:{n}: {what}: {line.strip()}")
                    hits += 1
print(f"{files} files in {', '.join(DIRS)}, {hits} literals outside their one definition")
sys.exit(1 if hits else 0)
