#!/usr/bin/env python3
"""Writes the generated seeds of tests/fuzz/corpus: the binary operation sequences of fuzz_can_dispatch
and fuzz_sdo_server (formats in the comments at the top of those harnesses) and rig-like candump logs.
The EDS, CSV and model JSON seeds are plain files kept by hand. Run from anywhere; rewrites its files."""
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
CORPUS = os.path.join(HERE, "corpus")


def write(target, name, data):
    d = os.path.join(CORPUS, target)
    os.makedirs(d, exist_ok=True)
    mode = "wb" if isinstance(data, (bytes, bytearray)) else "w"
    with open(os.path.join(d, name), mode) as f:
        f.write(data)


# ---- fuzz_can_dispatch ----

def frame(cob, data=b"", flags=0):
    """Frame operation: opcode with identifier bits 7-10, low identifier bits, DLC/flags byte, data."""
    op = ((cob >> 7) & 0x0F) << 3  # op & 7 == 0: a frame
    dlc = len(data) | ((0x80 | (flags << 4)) if flags else 0)
    return bytes([op, cob & 0x7F, dlc]) + bytes(data)


def us10(n):  # advance (n + 1) * 10 us
    return bytes([4, n])


def ms(n):  # advance (n + 1) ms
    return bytes([5, n - 1])


def long_ms(n):  # advance n ms (< 1500)
    return bytes([6]) + struct.pack("<H", n)


def repeat(times):
    return bytes([7 | ((times - 1) << 3)])


def sdo_write(node, index, sub, value, size):
    cmd = {1: 0x2F, 2: 0x2B, 4: 0x23}[size]
    return frame(0x600 + node, bytes([cmd]) + struct.pack("<HB", index, sub) + value.to_bytes(4, "little"))


NMT_START_ALL = frame(0x000, b"\x01\x00")


def cycle(k, y_um, p_raw, u_raw):
    """One rig cycle as the nodes would send it: SYNC, sensor position, valve pressure, command."""
    return (frame(0x080) + frame(0x182, struct.pack("<i", y_um)) + frame(0x183, struct.pack("<h", p_raw)) +
            frame(0x203, struct.pack("<h", u_raw)) + us10(99))


def dispatch_seeds():
    write("fuzz_can_dispatch", "boot_operational_run", bytes([1]) + ms(20) + long_ms(600))
    write("fuzz_can_dispatch", "nmt_start_and_cycles",
          bytes([0]) + NMT_START_ALL + b"".join(cycle(k, 1000 * k, 3277, 16384 + 100 * k) for k in range(12)))
    write("fuzz_can_dispatch", "heartbeats_emcy_timeout",
          bytes([1]) + frame(0x702, b"\x05") + frame(0x703, b"\x7f") + ms(50) + frame(0x702, b"\x04") +
          frame(0x082, bytes([0x30, 0x81, 0x11, 1, 2, 3, 4, 5])) + frame(0x083, bytes([0, 0, 0, 0, 0, 0, 0, 0])) +
          long_ms(400) + frame(0x702, b"\x00") + frame(0x702, b"\x05") + ms(10))
    write("fuzz_can_dispatch", "sdo_reconfigure_pdos",
          bytes([1]) +
          sdo_write(3, 0x1400, 1, 0x80000203, 4) +   # valve RPDO1 off
          sdo_write(3, 0x1600, 0, 0, 1) +            # mapping count 0
          sdo_write(3, 0x1600, 1, 0x64110110, 4) +   # map 0x6411:01, 16 bits
          sdo_write(3, 0x1600, 0, 1, 1) +
          sdo_write(3, 0x1400, 2, 0xFF, 1) +         # event driven
          sdo_write(3, 0x1400, 1, 0x00000203, 4) +   # on again
          frame(0x203, b"\x00\x40") + ms(5) +
          sdo_write(2, 0x1017, 0, 20, 2) +           # sensor heartbeat 20 ms
          sdo_write(1, 0x1006, 0, 2000, 4) +         # controller SYNC period 2 ms
          ms(30))
    write("fuzz_can_dispatch", "resets_and_odd_frames",
          bytes([1]) + ms(3) + frame(0x000, b"\x82\x00") + ms(3) + frame(0x000, b"\x81\x02") +
          frame(0x080, b"", flags=2) +                  # remote SYNC
          frame(0x182, b"\x01\x02\x03\x04", flags=1) +  # 29-bit
          frame(0x004, b"\x00" * 8, flags=4) +          # error frame
          frame(0x000, b"\x01") + frame(0x080, b"\x01") + frame(0x182, b"\x01\x02") +  # wrong lengths
          frame(0x000, b"\x07\x00") + NMT_START_ALL + ms(3))
    write("fuzz_can_dispatch", "sync_burst",
          bytes([1]) + frame(0x080) + repeat(32) + frame(0x203, b"\xff\x7f") + repeat(8) + us10(200))
    write("fuzz_can_dispatch", "stop_preop_start",
          bytes([1]) + ms(2) + frame(0x000, b"\x02\x00") + ms(2) + frame(0x080) + frame(0x000, b"\x80\x00") +
          ms(2) + frame(0x000, b"\x01\x03") + cycle(0, 5000, 100, 20000) + ms(2))


# ---- fuzz_sdo_server ----

def entry(index, sub):
    return bytes([0xF0]) + struct.pack("<HB", index, sub)


def dl_exp(index, sub, value, size=None):
    op = 0 if size is None else (0x08 | ((4 - size) << 4))
    return bytes([op]) + entry(index, sub) + value.to_bytes(4, "little")


def dl_init(index, sub, size=None, big=False):
    if size is None:
        return bytes([1]) + entry(index, sub)
    if big:
        return bytes([1 | 0x08 | 0x10]) + entry(index, sub) + struct.pack("<I", size)
    return bytes([1 | 0x08]) + entry(index, sub) + bytes([size])


def dl_seg(payload, last, wrong_toggle=False):
    n = 7 - len(payload)
    c = (1 if last else 0) | (n << 1) | (0x80 if wrong_toggle else 0)
    return bytes([2, c]) + payload + b"\x00" * n


def dl_segmented(index, sub, data, sized=True):
    out = dl_init(index, sub, len(data) if sized else None)
    chunks = [data[i:i + 7] for i in range(0, len(data), 7)] or [b""]
    for i, c in enumerate(chunks):
        out += dl_seg(c, i == len(chunks) - 1)
    return out


def ul(index, sub, segments=0):
    return bytes([3]) + entry(index, sub) + bytes([4]) * segments


def raw(data):
    return bytes([5]) + bytes(data)


def wait_100us(n):
    return bytes([6]) + struct.pack("<H", n)


def nmt(which, all_nodes=False):  # 0 start, 1 stop, 2 pre-op, 3 reset node, 4 reset comm
    return bytes([7 | (which << 3) | (0x80 if all_nodes else 0)])


def sdo_seeds():
    write("fuzz_sdo_server", "controller_expedited",
          bytes([0]) + ul(0x1000, 0) + ul(0x1018, 1) + dl_exp(0x1017, 0, 100, 2) + ul(0x1017, 0) +
          dl_exp(0x1017, 0, 100) + dl_exp(0x1006, 0, 1000, 4) + ul(0x9999, 0) + ul(0x1018, 9))
    write("fuzz_sdo_server", "controller_real64_segmented",
          bytes([4]) + dl_segmented(0x2000, 1, struct.pack("<d", 2.5)) + ul(0x2000, 1, 2) +
          dl_segmented(0x2000, 2, struct.pack("<d", -1.0), sized=False) + ul(0x1008, 0, 3))
    write("fuzz_sdo_server", "sensor_pdo_params",
          bytes([1]) + dl_exp(0x1800, 1, 0x80000182, 4) + dl_exp(0x1A00, 0, 0, 1) + dl_exp(0x1800, 3, 10, 2) +
          dl_exp(0x1800, 1, 0x182, 4) + ul(0x1A00, 1) + ul(0x1800, 5))
    write("fuzz_sdo_server", "valve_errors",
          bytes([2]) + dl_exp(0x1000, 0, 1, 4) + dl_exp(0x1003, 0, 0, 1) + dl_exp(0x1003, 0, 3, 1) +
          raw([0xA0, 0x00, 0x10, 0x00, 0, 0, 0, 0]) + raw([0xE0] + [0] * 7) + bytes([0x47, 1, 2, 3]) + ul(0x6411, 1))
    write("fuzz_sdo_server", "transfer_string_domain",
          bytes([3]) + dl_segmented(0x2000, 0, b"a longer name for this node") + ul(0x2000, 0, 4) +
          dl_segmented(0x2001, 0, bytes(range(40)), sized=False) + ul(0x2001, 0, 6) +
          dl_segmented(0x2002, 0, b"\x01\x02\x03") + ul(0x2002, 0) + ul(0x1008, 0, 6))
    write("fuzz_sdo_server", "transfer_toggle_abort_timeout",
          bytes([3]) + dl_init(0x2001, 0, 30) + dl_seg(b"1234567", False) + dl_seg(b"1234567", False, True) +
          dl_init(0x2001, 0, 30) + dl_seg(b"1234567", False) + raw([0x80, 0x01, 0x20, 0, 0, 0, 4, 5]) +
          dl_seg(b"1234567", False) + ul(0x1008, 0, 1) + bytes([4 | 0x08]) +
          dl_init(0x2000, 0, 10) + wait_100us(12000) + dl_seg(b"abc", True) +
          dl_init(0x2001, 0, 1000, big=True) + dl_init(0x2100, 1, 9))
    write("fuzz_sdo_server", "transfer_nmt_midway",
          bytes([7]) + dl_init(0x2001, 0) + dl_seg(b"1234567", False) + nmt(1) + dl_seg(b"1234567", False) +
          nmt(2) + dl_seg(b"1234567", True) + ul(0x2001, 0, 1) + nmt(4) + bytes([4]) +
          dl_exp(0x2100, 4, 2, 1) + dl_exp(0x2100, 1, 0, 4) + dl_segmented(0x2100, 2, struct.pack("<Q", 2**63)) +
          bytes([7 | 0x40 | (3 << 3), 0x40, 0x00, 0x10]) + nmt(3, True) + ul(0x2000, 0, 1))
    # Finding: the EMCY COB-ID could be set to the node's own SDO request identifier (0x603).
    write("fuzz_sdo_server", "regress_emcy_cobid_sdo",
          bytes([2]) + dl_exp(0x1014, 0, 0x46464603) + nmt(1) + nmt(0, True) + dl_exp(0x1018, 0, 0xF0))
    # Finding: the SDO timeout abort of a transfer went out while the node was Stopped.
    write("fuzz_sdo_server", "regress_stopped_timeout",
          bytes([3]) + dl_init(0x2001, 0) + dl_seg(b"1234567", False) + nmt(1) + wait_100us(24932) +
          nmt(2) + dl_seg(b"123\x04\x02\x00\x00", False))


# ---- fuzz_candump ----

def candump_line(t_us, cob, data, iface="vcan0"):
    return "(%d.%06d) %s %03X#%s" % (t_us // 1000000, t_us % 1000000, iface, cob, data.hex().upper())


def rig_log(cycles, lose=(), t0=1700000000000000, period=1000):
    lines = []
    for k in range(cycles):
        t = t0 + k * period
        lines.append(candump_line(t, 0x080, b""))
        if k not in lose:
            lines.append(candump_line(t + 100, 0x182, struct.pack("<i", 1000 * k)))
        lines.append(candump_line(t + 200, 0x183, struct.pack("<h", 3277)))
        lines.append(candump_line(t + 300, 0x203, struct.pack("<h", 16384 + 500 * k)))
    return lines


def candump_seeds():
    write("fuzz_candump", "rig_10_cycles.log", "\n".join(rig_log(10)) + "\n")
    write("fuzz_candump", "rig_lost_frames.log", "\n".join(rig_log(10, lose=(3, 4))) + "\n")
    svc = [candump_line(1700000000000000, 0x000, b"\x01\x00"), candump_line(1700000000000100, 0x701, b"\x05"),
           candump_line(1700000000000200, 0x081, bytes([0x30, 0x81, 0x11, 0, 0, 0, 0, 0])),
           candump_line(1700000000000300, 0x602, bytes([0x40, 0x17, 0x10, 0, 0, 0, 0, 0])),
           candump_line(1700000000000400, 0x582, bytes([0x4B, 0x17, 0x10, 0, 100, 0, 0, 0])),
           "(1700000000.000500) vcan0 123#R", "(1700000000.000600) vcan0 123#R4",
           "(1700000000.000700) vcan0 1ABCDEF0#DEAD", "(1700000000.000800) vcan0 20000004#0000000000000000",
           "(1700000000.000900) can1 182#01.02.03.04 T"]
    write("fuzz_candump", "services_and_frame_kinds.log", "\n".join(svc + rig_log(4, t0=1700000000001000)) + "\n")
    write("fuzz_candump", "crlf_and_blank_lines.log", "\r\n".join(rig_log(3)) + "\r\n\r\n   \r\n")
    write("fuzz_candump", "bad_line_at_end.log", "\n".join(rig_log(4)) + "\n(1700000000.9) vcan0 18#01\n")
    write("fuzz_candump", "uneven_timestamps.log", "\n".join(rig_log(6, period=1700)) + "\n")
    # Finding: more than 12 digits of seconds overflowed before they were refused.
    write("fuzz_candump", "regress_long_seconds.log",
          "(1700000000.000000) vcan0 080#\n(17000000000001700000000.000000) vcan0 080#\n")


if __name__ == "__main__":
    dispatch_seeds()
    sdo_seeds()
    candump_seeds()
