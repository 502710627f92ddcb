#include "rig/bus_fault_rig.hpp"

#include "nodes/process_data.hpp"

#include <malloc.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>

#include "canopen/bus.hpp"
#include "canopen/eds.hpp"
#include "canopen/node.hpp"
#include "nodes/emulator_node.hpp"
#include "plant/plant.hpp"

namespace pamc::rig {

using namespace detail;
using namespace nodes;

namespace {

// An SDO client made of raw frames on the rig's spare port, so a test can put SYNCs between the
// frames of one transfer.
struct SdoTool {
  explicit SdoTool(Rig& r) : r(r) {
    r.bus.addTap([this](const Frame& f, TimeUs) {
      if (f.id == 0x581 && f.len == 8) {
        response = f;
        answered = true;
      }
    });
  }
  Frame request(std::uint8_t cmd, std::uint16_t idx, std::uint8_t sub, const std::uint8_t* d, std::size_t n) {
    std::uint8_t b[8] = {cmd, static_cast<std::uint8_t>(idx), static_cast<std::uint8_t>(idx >> 8), sub, 0, 0, 0, 0};
    std::memcpy(b + 4, d, std::min<std::size_t>(n, 4));
    return canopen::makeFrame(0x601, 8, b);
  }
  // Sends f and runs the bus (gap_us per step) until the server answers; returns the response.
  Frame exchange(const Frame& f, TimeUs gap_us) {
    answered = false;
    r.aux.send(f);
    for (int i = 0; i < 1000 && !answered; ++i) r.step(gap_us);
    return response;
  }
  static std::uint32_t code(const Frame& f) { return f.data[0] == 0x80 ? canopen::getU32(f.data + 4) : 0; }
  // Expedited download of 1, 2 or 4 bytes.
  std::uint32_t write(std::uint16_t idx, std::uint8_t sub, const void* v, std::size_t n) {
    const std::uint8_t cmd = static_cast<std::uint8_t>(0x23 | ((4 - n) << 2));
    return code(exchange(request(cmd, idx, sub, static_cast<const std::uint8_t*>(v), n), 100));
  }
  std::uint32_t writeU8(std::uint16_t idx, std::uint8_t sub, std::uint8_t v) { return write(idx, sub, &v, 1); }
  std::uint32_t writeU32(std::uint16_t idx, std::uint8_t sub, std::uint32_t v) { return write(idx, sub, &v, 4); }
  // Segmented download of a REAL64; gap_us of bus time (with its SYNCs) between the frames.
  std::uint32_t writeDouble(std::uint16_t idx, std::uint8_t sub, double v, TimeUs gap_us = 100,
                            const std::function<void()>& between = {}) {
    std::uint8_t d[8];
    std::memcpy(d, &v, 8);
    const std::uint8_t size[4] = {8, 0, 0, 0};
    Frame f = exchange(request(0x21, idx, sub, size, 4), gap_us);
    if (code(f) != 0) return code(f);
    std::uint8_t seg1[8] = {0x00, d[0], d[1], d[2], d[3], d[4], d[5], d[6]};
    f = exchange(canopen::makeFrame(0x601, 8, seg1), gap_us);
    if (code(f) != 0) return code(f);
    if (between) between();
    std::uint8_t seg2[8] = {0x1D, d[7], 0, 0, 0, 0, 0, 0};  // toggle 1, 6 bytes unused, last
    return code(exchange(canopen::makeFrame(0x601, 8, seg2), gap_us));
  }
  void nmt(std::uint8_t cmd) {
    const std::uint8_t b[2] = {cmd, 1};
    r.aux.send(canopen::makeFrame(0x000, 2, b));
    r.step(kPeriod);
  }
  Rig& r;
  Frame response;
  bool answered = false;
};

std::string hexCode(std::uint32_t c) {
  char b[24];
  std::snprintf(b, sizeof b, c ? "0x%08X" : "accepted", c);
  return b;
}

}  // namespace

std::vector<GuardRow> runParameterGuards(const FaultRigOptions& o) {
  Rig r(BusFault::None, o);
  SdoTool sdo(r);
  while (r.ctrl->runTime() < 2.0) r.step(kPeriod);
  std::vector<GuardRow> rows;
  auto& od = r.ctrl->node().od();
  const double kp0 = r.ctrl->activeParameters().kp;
  char b[256];
  // The set in use before a write, to tell whether the loop saw anything of it.
  struct Snapshot {
    double kp, ki, gamma, safe;
    int kind;
    bool operator==(const Snapshot& o) const {
      return kp == o.kp && ki == o.ki && gamma == o.gamma && safe == o.safe && kind == o.kind;
    }
  };
  auto snap = [&] {
    const auto& p = r.ctrl->activeParameters();
    return Snapshot{p.kp, p.ki, p.model.core().gamma, r.ctrl->safeCommand(), static_cast<int>(r.ctrl->kind())};
  };
  Snapshot before = snap();
  auto unchanged = [&] { return snap() == before ? "refused; the loop's set is unchanged" : "LOOP CHANGED"; };
  auto row = [&](const std::string& what, std::uint32_t expected, std::uint32_t got, const std::string& effect) {
    rows.push_back({what, expected, got, effect});
    before = snap();
  };
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  using namespace canopen;
  row("0x1001 error register (ro)", kAbortReadOnly, sdo.writeU8(0x1001, 0, 1), unchanged());
  row("0x2003:02 staged flag (ro)", kAbortReadOnly, sdo.writeU8(0x2003, 2, 1), unchanged());
  row("0x2004 (no such object)", kAbortNoObject, sdo.writeU8(0x2004, 0, 1), unchanged());
  row("0x2000:0D (no such sub-index)", kAbortNoSubIndex, sdo.writeDouble(0x2000, 13, 1.0), unchanged());
  row("kp 0x2000:01 = 20 V/mm (above the EDS limit 10)", kAbortValueTooHigh, sdo.writeDouble(0x2000, 1, 20.0),
      unchanged());
  row("kp 0x2000:01 = 5000 (far above the EDS limit 10)", kAbortValueTooHigh, sdo.writeDouble(0x2000, 1, 5000.0),
      unchanged());
  row("kp 0x2000:01 = -1", kAbortValueTooLow, sdo.writeDouble(0x2000, 1, -1.0), unchanged());
  row("ki 0x2000:02 = NaN", kAbortValueRange, sdo.writeDouble(0x2000, 2, nan), unchanged());
  row("ESO b0 0x2000:08 = 0", kAbortValueTooLow, sdo.writeDouble(0x2000, 8, 0.0), unchanged());
  row("ESO wo 0x2000:0B = 0", kAbortValueTooLow, sdo.writeDouble(0x2000, 11, 0.0), unchanged());
  row("ESO form 0x2000:0C = 3 (above the EDS limit 2)", kAbortValueTooHigh, sdo.writeU8(0x2000, 12, 3), unchanged());
  row("UKF R0 0x2002:05 = 0", kAbortValueTooLow, sdo.writeDouble(0x2002, 5, 0.0), unchanged());
  row("UKF divergence bound 0x2002:09 = -1", kAbortValueTooLow, sdo.writeDouble(0x2002, 9, -1.0), unchanged());
  row("model k 0x2001:01 = inf", kAbortValueRange, sdo.writeDouble(0x2001, 1, inf), unchanged());
  row("stuck-sensor span 0x2022:03 = 20 V (above 10)", kAbortValueTooHigh, sdo.writeDouble(0x2022, 3, 20.0),
      unchanged());
  row("measuring range 0x2022:01 = 0", kAbortValueTooLow, sdo.writeDouble(0x2022, 1, 0.0), unchanged());
  row("safe valve voltage 0x2020 = 12 V", kAbortValueTooHigh, sdo.writeDouble(0x2020, 0, 12.0), unchanged());
  row("controller 0x2010 = 1 (PI) while Operational", kAbortDeviceState, sdo.writeU8(0x2010, 0, 1),
      snap() == before ? "refused; the controller is not switched under the running loop" : "LOOP CHANGED");
  row("trajectory 0x2011 = 2 while Operational", kAbortDeviceState, sdo.writeU8(0x2011, 0, 2), unchanged());
  row("SYNC period 0x1006 = 500 us while Operational", kAbortDeviceState, sdo.writeU32(0x1006, 0, 500), unchanged());
  row("heartbeat consumer 0x1016:01 = 0 while Operational", kAbortDeviceState, sdo.writeU32(0x1016, 1, 0),
      "refused; the sensor stays monitored");
  {
    const std::uint16_t zero = 0;
    row("valve command 0x3002 = 0 while Operational", kAbortDeviceState, sdo.write(0x3002, 0, &zero, 2),
        "refused; only the loop writes the valve");
  }
  row("position 0x3000 = 0 while Operational", kAbortDeviceState, sdo.writeU32(0x3000, 0, 0),
      "refused; only the sensor's PDO writes the position");
  // A segmented write with SYNCs between its frames: the entry changes with the last segment only.
  {
    bool half_written_seen = false;
    const std::uint32_t c = sdo.writeDouble(0x2000, 1, 0.12, 1000, [&] {
      for (int k = 0; k < 3; ++k) r.step(kPeriod);
      half_written_seen = od.entry(0x2000, 1).get<double>() != kp0;
    });
    for (int k = 0; k < 50; ++k) r.step(kPeriod);
    std::snprintf(
        b, sizeof b, "%s; staged (0x2003:02 = %u): after 50 cycles the loop still uses kp = %g",
        half_written_seen ? "ENTRY CHANGED BEFORE THE LAST SEGMENT" : "entry unchanged until the last segment",
        od.entry(0x2003, 2).get<std::uint8_t>(), r.ctrl->activeParameters().kp);
    row("kp 0x2000:01 = 0.12, segmented, 3 SYNCs between its segments", kSdoOk, c, b);
  }
  row("ki 0x2000:02 = 1.8", kSdoOk, sdo.writeDouble(0x2000, 2, 1.8), "staged");
  {
    // Commit: checked in the SDO server, taken by the loop at the next SYNC.
    const double step_before = [&] {
      double m = 0;
      for (std::size_t i = r.recs.size() - 500; i < r.recs.size(); ++i)
        m = std::max(m, std::fabs(r.recs[i].u - r.recs[i - 1].u));
      return m;
    }();
    const std::uint8_t applied0 = od.entry(0x2003, 3).get<std::uint8_t>();
    const std::size_t from = r.recs.size();
    const std::uint32_t c = sdo.writeU8(0x2003, 1, 1);
    const double kp_right_after = r.ctrl->activeParameters().kp;
    int cycles = 0;
    while (r.ctrl->activeParameters().kp != 0.12 && cycles < 10) r.step(kPeriod), ++cycles;
    for (int k = 0; k < 3000; ++k) r.step(kPeriod);
    double m = 0;
    for (std::size_t i = std::max<std::size_t>(from, 1); i < r.recs.size(); ++i)
      m = std::max(m, std::fabs(r.recs[i].u - r.recs[i - 1].u));
    std::snprintf(b, sizeof b,
                  "kp %g until the cycle boundary, then kp %g, ki %g in use; 0x2003:03 %u -> %u; largest command step "
                  "in the next 3 s %.4f V (before %.4f V)",
                  kp_right_after, r.ctrl->activeParameters().kp, r.ctrl->activeParameters().ki, applied0,
                  od.entry(0x2003, 3).get<std::uint8_t>(), m, step_before);
    row("commit 0x2003:01 = 1", kSdoOk, c, b);
  }
  row("model gamma 0x2001:06 = -0.5 (beta + gamma < 0)", kSdoOk, sdo.writeDouble(0x2001, 6, -0.5), "staged");
  {
    const double gamma = r.ctrl->activeParameters().model.core().gamma;
    const std::uint32_t c = sdo.writeU8(0x2003, 1, 1);
    r.step(kPeriod);
    std::snprintf(b, sizeof b, "refused: the loop keeps gamma = %g; the SDO answer carries the reason",
                  r.ctrl->activeParameters().model.core().gamma);
    (void)gamma;
    row("commit 0x2003:01 = 1 of that unstable model", kAbortParameterIncompatible, c, b);
  }
  {
    const std::uint32_t c = sdo.writeU8(0x2003, 1, 0);
    std::snprintf(b, sizeof b, "discarded: 0x2001:06 reads %g again, 0x2003:02 = %u", od.entry(0x2001, 6).get<double>(),
                  od.entry(0x2003, 2).get<std::uint8_t>());
    row("discard 0x2003:01 = 0", kSdoOk, c, b);
  }
  row("0x2003:01 = 2", kAbortValueTooHigh, sdo.writeU8(0x2003, 1, 2), unchanged());
  {
    // Switching the controller: stop the loop (NMT Pre-operational), write, start again.
    sdo.nmt(0x80);
    for (int k = 0; k < 5; ++k) r.step(kPeriod);
    const double valve = r.emu->valveVolts();
    const std::uint32_t c = sdo.writeU8(0x2010, 0, 1);
    sdo.nmt(0x01);
    for (int k = 0; k < 100; ++k) r.step(kPeriod);
    std::snprintf(b, sizeof b,
                  "valve at %g V (its error value) while the controller was Pre-operational; %s runs after NMT start",
                  valve, control::toString(r.ctrl->kind()));
    row("controller 0x2010 = 1 (PI) in Pre-operational", kSdoOk, c, b);
  }
  return rows;
}

std::string guardTableMarkdown(const std::vector<GuardRow>& rows) {
  std::string s =
      "| SDO write to the running controller | expected | answer | what the loop saw |\n|---|---|---|---|\n";
  for (const auto& r : rows) {
    s += "| " + r.write + " | " + hexCode(r.expected) + " | " + hexCode(r.got) +
         (r.got == r.expected ? "" : " (UNEXPECTED)") + " | " + r.effect + " |\n";
  }
  return s;
}

}  // namespace pamc::rig
