#!/usr/bin/env python3
"""One place per fact: the valve's command range, the bus delay and the NMT start-up object are written
once (src/control/actuation.hpp, canopen/nmt_master.hpp), the default gains once (control::kDefaultGains
in src/control/controller.hpp); the code of the nodes, the controllers, the command line, the rig and the
experiments derives from them. Greps src/nodes, src/control, src/app and src/rig (the gains: src/sim too;
comments and strings left out) for their literals. Parameter bounds of effects and probes are not such
facts. Prints one line per hit and a summary line; exit 1 on any hit."""
import pathlib
import re
import sys

src = pathlib.Path(sys.argv[1])
DIRS = ["src/nodes", "src/control", "src/app", "src/rig"]
DEFINITIONS = {"src/control/actuation.hpp", "canopen/nmt_master.hpp"}
GAINS_DEFINITION = "src/control/controller.hpp"
# (what, pattern on code without comments and strings)
FACTS = [
    ("the valve range as a literal", re.compile(r"(?<![\w.])-\s*5(\.0*)?(?![\w.])")),
    ("the valve range as a literal", re.compile(r"\b(u_min|u_max|safe_u|last_u)\w*\s*=\s*[-+]?\d")),
    ("the bus delay as a literal", re.compile(r"\bdelay_cycles\w*\s*=\s*\d")),
    ("a definition of the valve range or bus delay",
     re.compile(r"\b(kValveFullScale_V|kValveMid_V|kCommandMin|kCommandMax|kBusDelayCycles)\s*=\s*(?!\s|control::)")),
    ("0x1F80 as a literal (canopen::kObjStartup)", re.compile(r"\b0x1[fF]80\b")),
]
# Facts checked in more folders: the default gains (a gain set to a number other than 0, or a second set
# of defaults).
WIDE_DIRS = DIRS + ["src/sim"]
WIDE_FACTS = [
    ("a gain as a literal (control::kDefaultGains)", re.compile(r"\b(kp|ki|kc)\s*=\s*[-+]?(?!0(?![.\d]))\.?\d")),
    ("a definition of the default gains", re.compile(r"\bkDefaultGains\s*\{|\bkDefaultGains\s*=")),
]


def code_only(text):
    text = re.sub(r"/\*.*?\*/", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    return re.sub(r'"(\\.|[^"\\\n])*"', '""', text)


hits, files = 0, 0
for d in WIDE_DIRS:
    for p in sorted((src / d).rglob("*")):
        if p.suffix not in (".hpp", ".cpp", ".inc"):
            continue
        rel = str(p.relative_to(src))
        facts = [] if rel in DEFINITIONS else FACTS if d in DIRS else []
        facts = facts + ([] if rel == GAINS_DEFINITION else WIDE_FACTS)
        files += 1
        for n, line in enumerate(code_only(p.read_text()).splitlines(), 1):
            for what, pat in facts:
                if pat.search(line):
                    print(f"FAIL: {rel}:{n}: {what}: {line.strip()}")
                    hits += 1
print(f"{files} files in {', '.join(WIDE_DIRS)}, {hits} literals outside their one definition")
sys.exit(1 if hits else 0)
