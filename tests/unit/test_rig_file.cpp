// Rig files (od/rigs/*.ini, nodes/rig_file.hpp) and the controller as the NMT master that boots its
// slaves from one: bad files name the line; the shipped rig boots pamc's devices; slaves whose PDOs
// another master left scrambled are configured before anything runs; a slave with the wrong identity
// or one that refuses a write is reported (EMCY 0x6300, the SDO abort code) and left stopped; a slave
// that reboots is configured again.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "../common/rig_text.hpp"
#include "canopen/bus.hpp"
#include "canopen/candump_log.hpp"
#include "canopen/dcf.hpp"
#include "nodes/decoder.hpp"
#include "nodes/master_dcf.hpp"
#include "nodes/rig_file.hpp"
#include "plant/plant.hpp"
#include "rig/virtual_rig.hpp"

using namespace pamc;
using canopen::Frame;

namespace {

using test::kOd;
using test::writeTemp;

// The shipped rig in the one-muscle form with some lines replaced or added (the EDS paths made
// absolute): the form most of these tests edit.
std::string rigText(const test::Edits& edits = {}) { return test::oneMuscleRig(edits); }

nodes::ControllerNodeConfig controllerFromRig(const std::string& rig_path, std::vector<std::string>* log) {
  return test::rigController(nodes::readRigFile(rig_path), log);
}

nodes::EmulatorConfig emulator() { return test::pamcEmulator(); }

// A tool port: SDO requests to a node and NMT, answered on the ideal bus at once.
struct Tool {
  Tool(rig::VirtualRig& r) : rig(r), port(r.addPort()) {
    rig.addTap([this](const Frame& f, canopen::TimeUs) {
      if (f.id >= 0x581 && f.id <= 0x5FF) last = f;
      if (f.id > 0x80 && f.id < 0x100 && f.len == 8) emcy.push_back(canopen::getU16(f.data));
    });
  }
  std::uint32_t write32(std::uint8_t node, std::uint16_t idx, std::uint8_t sub, std::uint32_t v) {
    const std::uint8_t b[8] = {0x23,
                               static_cast<std::uint8_t>(idx),
                               static_cast<std::uint8_t>(idx >> 8),
                               sub,
                               static_cast<std::uint8_t>(v),
                               static_cast<std::uint8_t>(v >> 8),
                               static_cast<std::uint8_t>(v >> 16),
                               static_cast<std::uint8_t>(v >> 24)};
    port.send(canopen::makeFrame(0x600 + node, 8, b));
    rig.bus().flush();
    return last.data[0] == 0x80 ? canopen::getU32(last.data + 4) : 0;
  }
  std::uint32_t write8(std::uint8_t node, std::uint16_t idx, std::uint8_t sub, std::uint8_t v) {
    const std::uint8_t b[8] = {0x2F, static_cast<std::uint8_t>(idx), static_cast<std::uint8_t>(idx >> 8), sub, v, 0, 0,
                               0};
    port.send(canopen::makeFrame(0x600 + node, 8, b));
    rig.bus().flush();
    return last.data[0] == 0x80 ? canopen::getU32(last.data + 4) : 0;
  }
  // An SDO upload as the frames on the wire have it: expedited, or segmented with the toggle bit.
  std::vector<std::uint8_t> upload(std::uint8_t node, std::uint16_t idx, std::uint8_t sub,
                                   std::uint32_t* abort = nullptr) {
    const std::uint8_t init[8] = {
        0x40, static_cast<std::uint8_t>(idx), static_cast<std::uint8_t>(idx >> 8), sub, 0, 0, 0, 0};
    port.send(canopen::makeFrame(0x600 + node, 8, init));
    rig.bus().flush();
    std::vector<std::uint8_t> out;
    if (abort) *abort = last.data[0] == 0x80 ? canopen::getU32(last.data + 4) : 0;
    if (last.data[0] == 0x80) return out;
    if (last.data[0] & 0x02) {  // expedited
      const int n = (last.data[0] & 0x01) ? 4 - ((last.data[0] >> 2) & 3) : 4;
      return std::vector<std::uint8_t>(last.data + 4, last.data + 4 + n);
    }
    for (std::uint8_t toggle = 0;; toggle ^= 0x10) {
      const std::uint8_t seg[8] = {static_cast<std::uint8_t>(0x60 | toggle), 0, 0, 0, 0, 0, 0, 0};
      port.send(canopen::makeFrame(0x600 + node, 8, seg));
      rig.bus().flush();
      const int n = 7 - ((last.data[0] >> 1) & 7);
      out.insert(out.end(), last.data + 1, last.data + 1 + n);
      if (last.data[0] & 0x01) return out;
    }
  }
  std::uint64_t value(std::uint8_t node, std::uint16_t idx, std::uint8_t sub) {
    const auto b = upload(node, idx, sub);
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < b.size() && i < 8; ++i) v |= static_cast<std::uint64_t>(b[i]) << (8 * i);
    return v;
  }
  std::uint32_t read32(std::uint8_t node, std::uint16_t idx, std::uint8_t sub) {
    const auto b = upload(node, idx, sub);
    return b.size() == 4 ? canopen::getU32(b.data()) : 0xDEADBEEFu;
  }
  rig::VirtualRig& rig;
  canopen::VirtualBus::Port& port;
  Frame last{};
  std::vector<std::uint16_t> emcy;
};

// od/rigs/profile.ini with its EDS paths made absolute.
std::string profileRig() { return test::shippedRig("profile.ini"); }

// One of od/'s EDS files with some DefaultValues changed ({section, value}): a device whose configuration
// another master changed and stored (CiA 301 0x1010), so that a reset communication brings back that,
// not pamc's layout.
std::string edsWith(const std::string& file, const std::vector<std::pair<std::string, std::string>>& defaults) {
  std::ifstream in(kOd + file);
  std::string t((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const auto& [section, value] : defaults) {
    const auto sec = t.find("[" + section + "]\n");
    const auto key = t.find("DefaultValue=", sec);
    if (sec == std::string::npos || key == std::string::npos) {
      ADD_FAILURE() << file << " has no [" << section << "] DefaultValue";
      continue;
    }
    t.replace(key + 13, t.find('\n', key) - key - 13, value);
  }
  return writeTemp(file, t);
}

double trackingRmse(const std::vector<nodes::CycleRecord>& recs, double from_s) {
  double s = 0;
  int n = 0;
  for (const auto& r : recs)
    if (r.t >= from_s) s += (r.y - r.yd) * (r.y - r.yd), ++n;
  return n ? std::sqrt(s / n) : INFINITY;
}

}  // namespace

TEST(RigFile, TheShippedRigIsTheBuiltInLayout) {
  const auto rig = nodes::readRigFile(writeTemp("default.ini", test::shippedRig("default.ini")));
  ASSERT_EQ(rig.channels.size(), 1u);
  EXPECT_FALSE(rig.one_muscle_form);
  const auto& ch = rig.channels[0].cfg;
  EXPECT_EQ(ch.sensor_id, 2);
  EXPECT_EQ(ch.valve_id, 3);
  EXPECT_EQ(ch.layout.sensor_cob, 0x182u);
  EXPECT_EQ(ch.layout.valve_cob, 0x203u);
  EXPECT_EQ(ch.layout.feedback_cob, 0x183u);
  EXPECT_EQ(ch.position_rpdo, 1u);
  EXPECT_EQ(ch.feedback_rpdo, 2u);
  EXPECT_EQ(ch.command_tpdo, 1u);
  EXPECT_TRUE(ch.layout.scaling.isDefault());
  const auto& sensor_boot = rig.slave(2).boot;
  EXPECT_EQ(*sensor_boot.device_type, 0x00080196u);
  EXPECT_EQ(ch.layout.error_value_index, 0x6444);
  // 0x1F81: slave, boot, mandatory, not kept alive, 3 retries.
  EXPECT_EQ(sensor_boot.assignment, 0x0000030Du);
  const auto kept = nodes::readRigFile(writeTemp(
      "kept.ini", test::shippedRig("default.ini", {{"mandatory = yes          ; 0x1F81",
                                                    "keep_alive = yes\nretries = 5\nmandatory = yes ; 0x1F81"}})));
  EXPECT_EQ(kept.slave(2).boot.assignment, 0x0000051Du) << "bit 4 keep alive, bits 8-15 the retry factor";
  // The sensor's TPDO1: disabled, synchronous, mapped to 0x6004:00 (32 bits), enabled on 0x182.
  const auto& w = sensor_boot.writes;
  auto has = [&](std::uint16_t i, std::uint8_t s, std::uint64_t v, std::size_t n) {
    return std::find(w.begin(), w.end(), canopen::dcfValue(i, s, v, n)) != w.end();
  };
  EXPECT_TRUE(has(0x1800, 1, 0x80000182u, 4));
  EXPECT_TRUE(has(0x1800, 2, 1, 1));
  EXPECT_TRUE(has(0x1A00, 1, 0x60040020u, 4));
  EXPECT_TRUE(has(0x1800, 1, 0x182u, 4));
  EXPECT_TRUE(has(0x1017, 0, 100, 2));
  // It survives a concise DCF round trip (the standard carrier of a slave's configuration).
  const auto bytes = canopen::encodeConciseDcf(w);
  canopen::ConciseDcf back;
  std::string why;
  ASSERT_TRUE(canopen::decodeConciseDcf(bytes.data(), bytes.size(), back, &why)) << why;
  EXPECT_EQ(back, w);
  EXPECT_FALSE(canopen::decodeConciseDcf(bytes.data(), bytes.size() - 1, back, &why));
  EXPECT_NE(why.find("beyond the end"), std::string::npos) << why;
}

TEST(RigFile, ABadFileGetsOneLineNamingTheLine) {
  struct Case {
    std::vector<std::pair<std::string, std::string>> edits;
    std::string expect;  // in the message, after "rig.ini:"
  };
  const std::vector<Case> cases = {
      {{{"tpdo = 1 ", "tdpo = 1 "}}, "unknown key 'tdpo' in [sensor]"},
      {{{"heartbeat_ms = 100       ; 0x1017", "heartbeat_ms = fast ; 0x1017"}}, "heartbeat_ms 'fast' is not a number"},
      {{{"position = 0x6004:00", "position = 0x6004"}}, "is not an object"},
      {{{"position = 0x6004:00", "position = 0x6200:00"}}, "is not 32 bits"},
      {{{"position = 0x6004:00", "position = 0x6005:01"}}, "cannot be mapped into a PDO"},
      {{{"command = 0x6411:01", "command = 0x6444:01"}}, "is not a writable 16-bit object"},
      {{{"position = 0x6004:00", "position = 0x7004:00"}}, "has no object 0x7004:00"},
      {{{"[valve] ", "[valves] "}}, "unknown section [valves]"},
      {{{"[valve] ", "[sensor.sdo]\n6004 = 1\n[valve] "}}, "0x6004:00 is read-only"},
      {{{"[valve] ", "[sensor.sdo]\n60z4 = 1\n[valve] "}}, "is not an entry"},
      {{{"boot = yes               ; configure", "boot = maybe ; configure"}}, "boot 'maybe' is not yes or no"},
      {{{"node_id = 3", "node_id = 2"}}, "node-IDs of controller, sensor and valve must differ"},
      {{{"startup = 0x00000001", "startup = 0x00000010"}}, "only bits 0-3 of 0x1F80"},
      {{{"tpdo = 1 ", "tpdo = 7 "}}, "has no predefined COB-ID"},
      {{{"mandatory = yes          ; 0x1F81", "mandatory = yes\nmandatory = no ; 0x1F81"}},
       "duplicate key 'mandatory' in [sensor]"},
      {{{"mandatory = yes          ; 0x1F81", "reset = yes ; 0x1F81"}}, "reset: 0x1F81 bit 4 is keep alive"},
      {{{"mandatory = yes          ; 0x1F81", "retries = 256 ; 0x1F81"}}, "retries 256 is outside 0..255"},
  };
  for (const auto& c : cases) {
    const std::string path = writeTemp("rig.ini", rigText(c.edits));
    try {
      (void)nodes::readRigFile(path);
      ADD_FAILURE() << "accepted: " << c.expect;
    } catch (const nodes::RigError& e) {
      const std::string m = e.what();
      EXPECT_EQ(m.find('\n'), std::string::npos) << m;
      EXPECT_EQ(m.rfind(path + ":", 0), 0u) << m;
      EXPECT_NE(m.find(c.expect), std::string::npos) << m;
      // A problem with a key names its line: "path:N: ..." with N > 0.
      if (c.expect.find("must differ") == std::string::npos) {
        EXPECT_GT(std::atoi(m.c_str() + path.size() + 1), 0) << m;
      }
    }
  }
  EXPECT_THROW(nodes::readRigFile(::testing::TempDir() + "no-such.ini"), nodes::RigError);
}

// pamc's own devices from the shipped rig: checked, configured, read back, started; the loop runs.
TEST(RigBoot, TheShippedRigBootsTheEmulatorAndTheLoopRuns) {
  std::vector<std::string> log;
  rig::VirtualRig rig(controllerFromRig(writeTemp("default.ini", rigText()), &log), emulator());
  rig.start();
  rig.runFor(4.0);
  const auto fc = rig.controller().faultCounters();
  EXPECT_EQ(fc.slave_boots, 2u);
  EXPECT_EQ(fc.slave_boot_failures, 0u);
  EXPECT_EQ(fc.episodes, 0u);
  ASSERT_EQ(log.size(), 2u);
  EXPECT_NE(log[0].find("configuration written and read back"), std::string::npos) << log[0];
  EXPECT_TRUE(rig.controller().running());
  EXPECT_LT(trackingRmse(rig.records(), 1.0), 1.0);
}

// Another master left the sensor's position PDO asynchronous on another COB-ID and the valve's command
// PDO mapped to nothing: without the rig the loop never starts; with it the slaves are configured first.
TEST(RigBoot, SlavesScrambledBeforeTheControllerStartsAreConfigured) {
  auto scramble = [](rig::VirtualRig& rig, Tool& tool) {
    rig.startEmulator();
    for (std::uint8_t n : {2, 3}) {
      const std::uint8_t nmt[2] = {0x01, n};  // another master started them
      tool.port.send(canopen::makeFrame(0x000, 2, nmt));
    }
    rig.bus().flush();
    EXPECT_EQ(tool.write32(2, 0x1800, 1, 0x80000182u), 0u);
    EXPECT_EQ(tool.write8(2, 0x1800, 2, 254), 0u);
    EXPECT_EQ(tool.write32(2, 0x1800, 1, 0x190u), 0u);
    EXPECT_EQ(tool.write32(3, 0x1400, 1, 0x80000203u), 0u);
    EXPECT_EQ(tool.write8(3, 0x1600, 0, 0), 0u);
    EXPECT_EQ(tool.write32(3, 0x1400, 1, 0x203u), 0u);
  };
  {
    nodes::ControllerNodeConfig c = controllerFromRig(writeTemp("default.ini", rigText()), nullptr);
    c.channels[0].layout = nodes::SlaveLayout{};  // the built-in layout: nothing is configured
    c.dictionary.clear();
    rig::VirtualRig rig(c, emulator());
    Tool tool(rig);
    scramble(rig, tool);
    rig.startController();
    rig.runFor(3.0);
    EXPECT_TRUE(rig.records().empty() || trackingRmse(rig.records(), 0.0) > 3.0) << "the loop ran on scrambled slaves";
  }
  std::vector<std::string> log;
  rig::VirtualRig rig(controllerFromRig(writeTemp("default.ini", rigText()), &log), emulator());
  Tool tool(rig);
  scramble(rig, tool);
  rig.startController();
  rig.runFor(4.0);
  EXPECT_EQ(rig.controller().faultCounters().slave_boots, 2u);
  EXPECT_TRUE(rig.controller().running());
  EXPECT_LT(trackingRmse(rig.records(), 1.0), 1.0);
}

TEST(RigBoot, AWrongIdentityIsReportedAndTheSlaveLeftStopped) {
  std::vector<std::string> log;
  const auto path = writeTemp("rig.ini", rigText({{"device_type = 0x00080196", "device_type = 0x00020196"}}));
  rig::VirtualRig rig(controllerFromRig(path, &log), emulator());
  Tool tool(rig);
  rig.start();
  rig.runFor(2.0);
  const auto fc = rig.controller().faultCounters();
  EXPECT_EQ(fc.slave_boot_failures, 1u);
  EXPECT_NE(std::find(tool.emcy.begin(), tool.emcy.end(), 0x6300), tool.emcy.end()) << "EMCY 0x6300";
  ASSERT_FALSE(log.empty());
  EXPECT_NE(
      log.front().find(
          "sensor (node 2) not started, identity check: 0x1000:00 device type is 0x00080196, expected 0x00020196"),
      std::string::npos)
      << log.back();
  EXPECT_EQ(std::count_if(log.begin(), log.end(), [](const std::string& l) { return l.find("sensor (node 2)") == 0; }),
            1)
      << "one line for the failure";
  EXPECT_EQ(rig.controller().node().heartbeatConsumer().remoteState(2), canopen::NmtState::Stopped);
  EXPECT_FALSE(rig.controller().running()) << "no position: the loop does not start";
  EXPECT_TRUE(nodes::runFailure(rig.controller())) << "the run fails: pamc controller exits non-zero";
  // The valve is mandatory-gated too: nothing was started while the sensor failed.
  EXPECT_NE(rig.controller().node().heartbeatConsumer().remoteState(3), canopen::NmtState::Operational);
}

// Nothing is written to a slave before its boot has checked its identity (0x1018 against 0x1F85-0x1F88):
// no SDO download to the valve before the answer to the upload of its vendor-ID 0x1018:01. The error
// value 0x6444:01 is the valve driver's configuration in that boot (CiA 302-2, Lely's OnConfig): once,
// after the identity and after the concise DCF's read-back (the boot's last upload), before the valve's
// NMT start. A valve with the wrong vendor-ID gets no write at all.
TEST(RigBoot, NothingIsWrittenToTheValveBeforeItsIdentityIsChecked) {
  for (bool wrong : {false, true}) {
    SCOPED_TRACE(wrong ? "wrong vendor-ID" : "right vendor-ID");
    const std::string vendor = wrong ? "vendor_id = 0x00001234" : "vendor_id = 0x0000ABCD";
    const auto path = writeTemp(
        "rig.ini",
        rigText({{"vendor_id = 0x00000000\nproduct_code = 0x00000003", vendor + "\nproduct_code = 0x00000003"}}));
    nodes::EmulatorConfig e = emulator();
    e.valve_eds = edsWith("valve.eds", {{"1018sub1", "0x0000ABCD"}});
    rig::VirtualRig rig(controllerFromRig(path, nullptr), e);
    std::vector<std::string> frames;
    rig.addTap([&frames](const Frame& f, canopen::TimeUs) { frames.push_back(canopen::formatFrame(f)); });
    rig.start();
    rig.runFor(2.0);
    auto first = [&frames](auto pred) {
      return static_cast<std::size_t>(std::find_if(frames.begin(), frames.end(), pred) - frames.begin());
    };
    auto errorValue = [](const std::string& f) { return f.rfind("603#2", 0) == 0 && f.compare(6, 6, "446401") == 0; };
    const std::size_t identity = first([](const std::string& f) { return f.rfind("583#43181001", 0) == 0; });
    const std::size_t write = first([](const std::string& f) { return f.rfind("603#2", 0) == 0; });
    const std::size_t error_value = first(errorValue);
    const std::size_t start = first([](const std::string& f) { return f == "000#0103"; });
    std::size_t last_upload = 0;
    for (std::size_t i = 0; i < frames.size(); ++i)
      if (frames[i].rfind("603#40", 0) == 0) last_upload = i;
    ASSERT_LT(identity, frames.size()) << "the vendor-ID was read";
    EXPECT_EQ(rig.controller().faultCounters().slave_boot_failures, wrong ? 1u : 0u);
    if (wrong) {
      EXPECT_EQ(write, frames.size()) << "nothing written to a valve of another vendor, no 0x6444 either";
      EXPECT_EQ(start, frames.size()) << "nor started";
    } else {
      EXPECT_GT(write, identity) << frames[write];
      ASSERT_LT(error_value, frames.size()) << "the error value is written in the valve's boot";
      EXPECT_GT(error_value, last_upload) << "after the identity and the read-back";
      EXPECT_LT(error_value, start) << "before the valve's start";
      EXPECT_EQ(std::count_if(frames.begin(), frames.end(), errorValue), 1) << "once";
    }
  }
}

TEST(RigBoot, ARefusedWriteIsReportedWithItsAbortCode) {
  std::vector<std::string> log;
  const auto path = writeTemp("rig.ini", rigText() + "\n[valve.sdo]\n6411sub1 = -5\n");
  rig::VirtualRig rig(controllerFromRig(path, &log), emulator());
  rig.start();
  rig.runFor(2.0);
  // The boot report; the loop's own line (no position: the sensor waits for the valve) follows it.
  const auto line =
      std::find_if(log.begin(), log.end(), [](const std::string& l) { return l.find("valve (node 3)") == 0; });
  ASSERT_NE(line, log.end());
  EXPECT_NE(line->find("valve (node 3) not started, configuration: 0x6411:01 write refused"), std::string::npos)
      << *line;
  EXPECT_NE(line->find("SDO abort 0x06090032"), std::string::npos) << *line;
  EXPECT_EQ(rig.controller().node().heartbeatConsumer().remoteState(3), canopen::NmtState::Stopped);
}

TEST(RigBoot, ASlaveThatRebootsIsConfiguredAgain) {
  rig::VirtualRig rig(controllerFromRig(writeTemp("default.ini", rigText()), nullptr), emulator());
  rig.start();
  rig.runFor(3.0);
  ASSERT_EQ(rig.controller().faultCounters().slave_boots, 2u);
  rig.emulator().rebootSensor(200'000);
  rig.runFor(4.0);
  const auto fc = rig.controller().faultCounters();
  EXPECT_EQ(fc.slave_boots, 3u);
  EXPECT_GE(fc.recoveries, 1u);
  EXPECT_EQ(rig.controller().fault(), nodes::Fault::None);
}

// 0x1F80 bit 2 clear (the shipped rig): a reset of the controller brings the whole rig back - the
// controller enters Operational by itself, boots both slaves again and the loop runs. Bit 2 set: it
// waits in Pre-operational until an NMT start.
TEST(RigBoot, AResetControllerBringsTheRigBackUnlessToldToWait) {
  for (bool wait : {false, true}) {
    const auto path =
        writeTemp("rig.ini", wait ? rigText({{"startup = 0x00000001", "startup = 0x00000005"}}) : rigText());
    rig::VirtualRig rig(controllerFromRig(path, nullptr), emulator());
    Tool tool(rig);
    rig.start();
    rig.runFor(wait ? 0.5 : 3.0);
    if (wait) {
      EXPECT_EQ(rig.controller().node().nmtState(), canopen::NmtState::PreOperational);
      EXPECT_EQ(rig.controller().faultCounters().slave_boots, 0u) << "a waiting master boots nothing";
      const std::uint8_t start[2] = {0x01, 0x01};
      tool.port.send(canopen::makeFrame(0x000, 2, start));
      rig.runFor(3.0);
    }
    ASSERT_TRUE(rig.controller().running()) << "wait=" << wait;
    ASSERT_EQ(rig.controller().faultCounters().slave_boots, 2u);
    const std::uint8_t reset[2] = {0x81, 0x01};  // reset node: the controller
    tool.port.send(canopen::makeFrame(0x000, 2, reset));
    rig.runFor(1.0);
    if (wait) {
      EXPECT_EQ(rig.controller().node().nmtState(), canopen::NmtState::PreOperational);
      const std::uint8_t start[2] = {0x01, 0x01};
      tool.port.send(canopen::makeFrame(0x000, 2, start));
    }
    rig.runFor(3.0);
    EXPECT_EQ(rig.controller().node().nmtState(), canopen::NmtState::Operational) << "wait=" << wait;
    EXPECT_EQ(rig.controller().faultCounters().slave_boots, 4u) << "both slaves booted again";
    EXPECT_TRUE(rig.controller().running()) << "wait=" << wait;
  }
}

// Devices pamc did not make (emulator --profile-defaults): a CiA 406 encoder and a CiA 401 I/O module
// with their makers' defaults. Started by any master they talk asynchronously on their own COB-IDs and
// send no heartbeat; pamc's controller without a rig file never gets a position from them; with
// od/rigs/profile.ini it configures both (the 5 um step read from the encoder) and tracks as well as
// with its own devices.
TEST(RigBoot, DevicesWithTheirMakersDefaultsWorkOnlyWithTheirRigFile) {
  const auto profile = nodes::EmulatorConfig::profileDevices(kOd.substr(0, kOd.size() - 1));
  {
    nodes::ControllerNodeConfig c = controllerFromRig(writeTemp("default.ini", rigText()), nullptr);
    c.channels[0].layout = nodes::SlaveLayout{};
    c.dictionary.clear();
    rig::VirtualRig rig(c, profile);
    Tool tool(rig);
    std::vector<std::pair<canopen::TimeUs, Frame>> frames;
    rig.addTap([&](const Frame& f, canopen::TimeUs t) { frames.push_back({t, f}); });
    rig.startEmulator();
    const std::uint8_t all[2] = {0x01, 0x00};  // another master starts every node
    tool.port.send(canopen::makeFrame(0x000, 2, all));
    rig.bus().flush();
    rig.runFor(0.1);
    int enc = 0, io = 0, hb = 0;
    for (const auto& [t, f] : frames) {
      if (f.id == 0x190) {
        ++enc;
        EXPECT_EQ(f.len, 6) << "position and alarms";
      }
      if (f.id == 0x1A0) {
        ++io;
        EXPECT_EQ(f.len, 8) << "four inputs";
      }
      if (f.id == 0x710 || f.id == 0x720) ++hb;
    }
    EXPECT_NEAR(enc, 10, 2) << "every 10 ms";
    EXPECT_NEAR(io, 5, 1) << "every 20 ms";
    EXPECT_EQ(hb, 2) << "their boot-ups only, no heartbeat";
    rig.startController();
    rig.runFor(3.0);
    EXPECT_FALSE(rig.controller().running()) << "pamc's layout on devices that differ";
  }
  std::vector<std::string> log;
  auto c = controllerFromRig(writeTemp("profile.ini", profileRig()), &log);
  rig::VirtualRig rig(c, profile);
  rig.start();
  rig.runFor(4.0);
  ASSERT_EQ(log.size(), 2u);
  EXPECT_EQ(rig.controller().faultCounters().slave_boots, 2u);
  EXPECT_DOUBLE_EQ(rig.controller().scaling().position_step_mm, 0.005) << "read from the encoder's 0x6005:01";
  EXPECT_TRUE(rig.controller().running());
  EXPECT_LT(trackingRmse(rig.records(), 1.0), 1.0);
  // The module watches the controller now: without its heartbeat the valve output goes to its error value.
  EXPECT_FALSE(rig.emulator().valveInError());
}

// A log of a run with the profile devices decodes through the rig file - its COB-IDs 0x190, 0x220,
// 0x1A0 and its scaling (5 um steps, 0..20000 counts) - to the positions the controller saw; through
// the EDS files alone (pamc's own COB-IDs) it has no position at all.
TEST(RigDecode, ALogOfTheProfileRigDecodesToThePositionsTheControllerSaw) {
  const auto path = writeTemp("profile.ini", profileRig());
  rig::VirtualRig rig(controllerFromRig(path, nullptr),
                      nodes::EmulatorConfig::profileDevices(kOd.substr(0, kOd.size() - 1)));
  std::vector<canopen::CandumpRecord> log;
  rig.addTap([&](const Frame& f, canopen::TimeUs t) {
    canopen::CandumpRecord r;
    r.unix_time_us = 1700000000000000 + t;
    r.interface = "vcan0";
    r.frame = f;
    log.push_back(r);
  });
  rig.start();
  rig.runFor(3.0);
  ASSERT_TRUE(rig.controller().running());
  const auto run = nodes::decodeCandump(log, nodes::busDictionaryFromRig(nodes::readRigFile(path)));
  ASSERT_GT(run.rows.size(), 2000u);
  EXPECT_EQ(run.columns.at(2), "y");
  EXPECT_EQ(run.held, 0u);
  // The controller works at SYNC k with the position sent after SYNC k-1: the same series one row on.
  const auto& recs = rig.records();
  ASSERT_GT(recs.size(), 2000u);
  std::vector<double> dec;
  for (const auto& r : run.rows) dec.push_back(r[2]);
  std::size_t best = 0;
  for (std::size_t off = 0; off + recs.size() <= dec.size(); ++off) {
    std::size_t same = 0;
    for (std::size_t i = 0; i < recs.size(); ++i) same += dec[off + i] == recs[i].y;
    best = std::max(best, same);
  }
  EXPECT_EQ(best, recs.size()) << "every position the controller saw, in order";
  // Scaled: the positions are millimetres of the sine 10-20 mm, not counts.
  const auto [lo, hi] = std::minmax_element(dec.begin(), dec.end());
  EXPECT_GT(*lo, -1.0);
  EXPECT_LT(*hi, 40.0);
  EXPECT_GT(*hi - *lo, 5.0);
  // The command in volts relative to mid-range, from 0..20000 counts.
  for (const auto& r : run.rows) {
    EXPECT_GE(r[1], -5.0 - 1e-9);
    EXPECT_LE(r[1], 5.0 + 1e-9);
  }
  EXPECT_TRUE(nodes::decodeCandump(log, nodes::loadBusDictionary({kOd})).rows.empty()) << "pamc's own COB-IDs";
}

// CiA 302-2 0x1F81 bits 8-15, the retry factor: an answer of the sensor is lost, the step times out
// (1 s) and is tried again; the boot completes and the loop runs. With `retries = 0` the boot fails there.
TEST(RigBoot, AnUnansweredBootStepIsTriedAgain) {
  for (int retries : {3, 0}) {
    std::vector<std::string> log;
    const auto path = writeTemp("rig.ini", retries == 3 ? rigText()
                                                        : rigText({{"boot = yes               ; configure at boot",
                                                                    "retries = 0\nboot = yes ; configure at boot"}}));
    int lost = 0;  // the sensor's first answer to the read of its product code 0x1018:02
    rig::VirtualRig rig(controllerFromRig(path, &log), emulator(), 0, [&](Frame& f) {
      return !(f.id == 0x582 && f.data[1] == 0x18 && f.data[2] == 0x10 && f.data[3] == 2 && lost++ == 0);
    });
    rig.start();
    rig.runFor(4.0);
    const auto& mc = rig.controller().master().counters();
    if (retries == 3) {
      EXPECT_EQ(mc.boot_retries, 1u);
      EXPECT_EQ(mc.boots, 2u);
      EXPECT_EQ(mc.boot_failures, 0u);
      EXPECT_TRUE(rig.controller().running());
    } else {
      EXPECT_EQ(mc.boot_retries, 0u);
      EXPECT_EQ(mc.boot_failures, 1u);
      const auto line =
          std::find_if(log.begin(), log.end(), [](const std::string& l) { return l.find("sensor (node 2)") == 0; });
      ASSERT_NE(line, log.end());
      EXPECT_NE(line->find("sensor (node 2) not started, identity check: 0x1018:02 read failed: SDO protocol timed out "
                           "(SDO abort 0x05040000)"),
                std::string::npos)
          << *line;
    }
  }
}

// The rig file compiled into the controller's own dictionary, as CiA 302 has it: what an SDO upload of
// 0x1F22:<node-ID> shows is the concise DCF the controller writes at the slave's boot, and it decodes
// back to the rig's entries; the expected identity is in 0x1F84-0x1F88, the assignment in 0x1F81, the
// consumer heartbeat times in 0x1016 (twice the slave's period plus 50 ms).
TEST(RigMaster, AnSdoUploadOfTheMastersObjectsShowsTheRigsBoot) {
  const auto path =
      writeTemp("rig.ini", rigText({{"heartbeat_ms = 100       ; 0x1017", "heartbeat_ms = 1000 ; 0x1017"}}));
  const auto rig = nodes::readRigFile(path);
  rig::VirtualRig vr(controllerFromRig(path, nullptr), emulator());
  Tool tool(vr);
  vr.start();
  vr.runFor(0.2);
  for (const auto& [id, boot] :
       {std::pair<std::uint8_t, const canopen::SlaveBoot*>{2, &rig.slave(2).boot}, {3, &rig.slave(3).boot}}) {
    const auto bytes = tool.upload(1, 0x1F22, id);
    ASSERT_GT(bytes.size(), 8u) << "node " << int(id) << ": a segmented upload";
    canopen::ConciseDcf back;
    std::string why;
    ASSERT_TRUE(canopen::decodeConciseDcf(bytes.data(), bytes.size(), back, &why)) << why;
    EXPECT_EQ(back, boot->writes) << "node " << int(id);
    EXPECT_EQ(tool.read32(1, 0x1F81, id), boot->assignment);
  }
  EXPECT_EQ(tool.read32(1, 0x1F84, 2), 0x00080196u) << "device type";
  EXPECT_EQ(tool.read32(1, 0x1F85, 2), 0u) << "vendor-ID 0: not checked";
  EXPECT_EQ(tool.read32(1, 0x1F86, 2), 2u) << "product code";
  EXPECT_EQ(tool.read32(1, 0x1F84, 3), 0x000C0191u);
  EXPECT_EQ(tool.read32(1, 0x1F88, 3), 0u) << "serial number not checked";
  EXPECT_EQ(tool.read32(1, 0x1F89, 0), 0u) << "no boot time";
  EXPECT_EQ(tool.read32(1, 0x1016, 1), 0x00020000u | 2050u) << "the sensor's 1000 ms heartbeat";
  EXPECT_EQ(tool.read32(1, 0x1016, 2), 0x00030000u | 250u) << "the valve's 100 ms heartbeat";
  EXPECT_EQ(tool.read32(1, 0x1F22, 4), 0xDEADBEEFu) << "node 4: nothing to write (empty)";
  // A concise DCF written over SDO must decode.
  std::uint32_t code = 0;
  tool.upload(1, 0x1F22, 2, &code);
  EXPECT_EQ(code, 0u);
  EXPECT_EQ(tool.write32(1, 0x1F22, 5, 0x00000002u), 0x06090030u) << "two entries announced, none there";
}

// The boot follows the dictionary, not the rig file: an expected device type changed over SDO makes the
// sensor's next boot (the controller's next start) fail on it.
TEST(RigMaster, TheBootFollowsTheMastersDictionary) {
  std::vector<std::string> log;
  const auto path = writeTemp("default.ini", rigText());
  rig::VirtualRig vr(controllerFromRig(path, &log), emulator());
  Tool tool(vr);
  vr.start();
  vr.runFor(2.0);
  ASSERT_TRUE(vr.controller().running());
  EXPECT_EQ(tool.write32(1, 0x1F84, 2, 0x00020196u), 0u);
  const std::uint8_t preop[2] = {0x80, 0x01}, start[2] = {0x01, 0x01};
  tool.port.send(canopen::makeFrame(0x000, 2, preop));
  vr.runFor(0.1);
  tool.port.send(canopen::makeFrame(0x000, 2, start));
  vr.runFor(2.0);
  EXPECT_EQ(vr.controller().faultCounters().slave_boot_failures, 1u);
  const auto line = std::find_if(log.begin(), log.end(),
                                 [](const std::string& l) { return l.find("sensor (node 2) not started") == 0; });
  ASSERT_NE(line, log.end());
  EXPECT_NE(line->find("device type is 0x00080196, expected 0x00020196"), std::string::npos) << *line;
}

// A master DCF written by hand (tests/dcf/moved_pdos.dcf): the sensor's position on 0x190 and the valve's
// command on 0x210 instead of the rig's 0x182 and 0x203, a 200 ms sensor heartbeat, both slaves kept
// alive with a retry factor of 2. On top of the shipped rig, the controller boots the slaves as the DCF
// says and tracks; the same with the sensor's concise DCF in a binary file named by UploadFile.
TEST(MasterDcf, TheControllerBootsTheSlavesFromAHandWrittenDcf) {
  const std::string fixture = std::string(PAMC_SOURCE_DIR) + "/tests/dcf/moved_pdos.dcf";
  std::ifstream in(fixture);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // The second form: 0x1F22:02 from a file (the bytes of the hand-written hex).
  std::string with_file = text;
  const auto at = with_file.find("ParameterValue=07000000");
  ASSERT_NE(at, std::string::npos);
  const auto eol = with_file.find('\n', at);
  std::string hex = with_file.substr(at + 15, eol - at - 15), bytes;
  hex.erase(std::remove(hex.begin(), hex.end(), ' '), hex.end());
  for (std::size_t i = 0; i + 1 < hex.size(); i += 2)
    bytes.push_back(static_cast<char>(std::stoi(hex.substr(i, 2), nullptr, 16)));
  std::ofstream(writeTemp("node2.bin", "")) << bytes;
  with_file.replace(
      at, eol - at,
      "UploadFile=" + ::testing::TempDir() + "MasterDcf.TheControllerBootsTheSlavesFromAHandWrittenDcf.node2.bin");
  for (const std::string& dcf : {fixture, writeTemp("moved.dcf", with_file)}) {
    std::vector<std::string> log;
    auto c = controllerFromRig(writeTemp("default.ini", rigText()), &log);
    nodes::applyMasterDcf(dcf, c);
    rig::VirtualRig vr(c, emulator());
    Tool tool(vr);
    int old_cobs = 0, new_cobs = 0;
    vr.addTap([&](const Frame& f, canopen::TimeUs t) {
      if (t < 1'000'000) return;
      old_cobs += f.id == 0x182 || f.id == 0x203;
      new_cobs += f.id == 0x190 || f.id == 0x210;
    });
    vr.start();
    vr.runFor(4.0);
    const auto fc = vr.controller().faultCounters();
    EXPECT_EQ(fc.slave_boots, 2u) << dcf;
    EXPECT_EQ(fc.slave_boot_failures, 0u);
    EXPECT_EQ(fc.episodes, 0u);
    EXPECT_TRUE(vr.controller().running());
    EXPECT_LT(trackingRmse(vr.records(), 1.0), 1.0);
    EXPECT_EQ(tool.read32(2, 0x1800, 1), 0x190u) << "the sensor's TPDO1";
    EXPECT_EQ(tool.read32(3, 0x1400, 1), 0x210u) << "the valve's RPDO1";
    EXPECT_EQ(tool.upload(2, 0x1017, 0), (std::vector<std::uint8_t>{200, 0})) << "the sensor's heartbeat";
    EXPECT_EQ(tool.read32(1, 0x1F81, 2), 0x0000021Du) << "kept alive, 2 retries";
    EXPECT_EQ(tool.read32(1, 0x1016, 1), 0x000201C2u);
    EXPECT_EQ(old_cobs, 0);
    EXPECT_GT(new_cobs, 5000) << "position and command every cycle on their new COB-IDs";
  }
}

// A DCF that is not one, or gives the controller what it cannot take: one line, "file:line: problem".
TEST(MasterDcf, AMalformedDcfIsOneLineNamingFileAndLine) {
  std::ifstream in(std::string(PAMC_SOURCE_DIR) + "/tests/dcf/moved_pdos.dcf");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  struct Case {
    std::string from, to, expect;
  };
  const std::vector<Case> cases = {
      {"ParameterValue=0x00000190", "ParameterValue=0x190Z",
       "[1400sub1] ParameterValue: '0x190Z' is not a valid UNSIGNED32"},
      {"NrOfEntries=2\n2=0x00000002", "NrOfEntries=3\n2=0x00000002", "NrOfEntries is 3 but 2 entries follow"},
      {"ParameterValue=07000000", "ParameterValue=08000000",
       "0x1F22:02 is not a concise DCF: entry 8 of 8: header beyond the end"},
      {"ParameterValue=07000000", "ParameterValue=0700000", "is not a sequence of hex bytes for DOMAIN"},
      {"2=0x0000021D", "2=0x10000021D", "'0x10000021D' is out of range for UNSIGNED32"},
      {"[1F86Value]\nNrOfEntries=2\n2=0x00000002", "[1F86Value]\nNrOfEntries=2\n200=0x00000002",
       "not a sub-index of the object (1..127)"},
      {"7=0x1F86", "7=0x1F8A", "listed object has no section"},
      {"ObjectType=0x7\nDataType=0x000F\nAccessType=rw\nParameterValue=07",
       "ObjectType=0x7\nDataType=0x000A\nAccessType=rw\nParameterValue=07",
       "0x1F22:02 is OCTET_STRING here but DOMAIN in"},
      {"[1F22sub2]", "[1F22sub80]", "the device"},
      {"[1F22sub2]", "[1F22subZZ]", "neither an object"},
  };
  for (const auto& c : cases) {
    std::string bad = text;
    const auto at = bad.find(c.from);
    ASSERT_NE(at, std::string::npos) << c.from;
    bad.replace(at, c.from.size(), c.to);
    const std::string path = writeTemp("bad.dcf", bad);
    auto cfg = controllerFromRig(writeTemp("default.ini", rigText()), nullptr);
    try {
      nodes::applyMasterDcf(path, cfg);
      ADD_FAILURE() << "accepted: " << c.expect;
    } catch (const canopen::EdsError& e) {
      const std::string m = e.what();
      EXPECT_EQ(m.find('\n'), std::string::npos) << m;
      EXPECT_EQ(m.rfind(path + ":", 0), 0u) << m;
      EXPECT_GT(e.line(), 0) << m;
      EXPECT_NE(m.find(c.expect), std::string::npos) << m;
    }
  }
}

// Slaves another master left otherwise - and stored, so that a reset communication does not undo it (their
// EDS defaults changed) - started by it before the controller comes: a moved TPDO COB-ID, a changed
// mapping, an asynchronous transmission type, a disabled RPDO, heartbeat 0 or 1000 ms. Without the rig
// file's configuration the loop does not run on most of them (an asynchronous position sent on every
// change and no heartbeat at all go unnoticed); with it the controller resets, checks and
// configures them (read back), waits for their first heartbeat, starts them, and the loop tracks.
TEST(RigBoot, SlavesAnotherMasterLeftOtherwiseAreConfiguredBeforeTheStart) {
  struct Case {
    const char* what;
    std::vector<std::pair<std::string, std::string>> sensor, valve;
    std::uint8_t node;
    std::uint16_t index;
    std::uint8_t sub;
    std::uint64_t left, configured;
    bool runs_unconfigured;
  };
  const std::vector<Case> cases = {
      {"a moved TPDO COB-ID", {{"1800sub1", "0x190"}}, {}, 2, 0x1800, 1, 0x190, 0x182, false},
      {"a changed mapping", {{"1A00sub1", "0x65030010"}}, {}, 2, 0x1A00, 1, 0x65030010, 0x60040020, false},
      // Sent on every change of the position, as often as it is sampled: the loop runs on it unconfigured.
      {"an asynchronous TPDO", {{"1800sub2", "254"}, {"1800sub5", "10"}}, {}, 2, 0x1800, 2, 254, 1, true},
      {"a disabled RPDO", {}, {{"1400sub1", "0x80000203"}}, 3, 0x1400, 1, 0x80000203, 0x203, false},
      {"heartbeat 0", {{"1017", "0"}}, {{"1017", "0"}}, 2, 0x1017, 0, 0, 100, true},
      {"heartbeat 1000 ms", {{"1017", "1000"}}, {{"1017", "1000"}}, 3, 0x1017, 0, 1000, 100, false},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.what);
    nodes::EmulatorConfig e = emulator();
    if (!c.sensor.empty()) e.sensor_eds = edsWith("sensor.eds", c.sensor);
    if (!c.valve.empty()) e.valve_eds = edsWith("valve.eds", c.valve);
    for (bool configured : {false, true}) {
      std::vector<std::string> log;
      auto cfg = controllerFromRig(writeTemp("default.ini", rigText()), &log);
      if (!configured) cfg.dictionary.clear(), cfg.channels[0].layout = nodes::SlaveLayout{};  // pamc's layout assumed
      rig::VirtualRig vr(cfg, e);
      Tool tool(vr);
      vr.startEmulator();
      const std::uint8_t all[2] = {0x01, 0x00};  // the other master started them
      tool.port.send(canopen::makeFrame(0x000, 2, all));
      vr.bus().flush();
      ASSERT_EQ(tool.value(c.node, c.index, c.sub), c.left);
      vr.startController();
      vr.runFor(5.0);
      const double rmse = trackingRmse(vr.records(), 2.0);
      if (!configured) {
        if (!c.runs_unconfigured) {
          EXPECT_TRUE(!vr.controller().running() || rmse > 3.0 || vr.controller().faultsRaised() > 0);
        }
        continue;
      }
      const auto fc = vr.controller().faultCounters();
      EXPECT_EQ(fc.slave_boots, 2u);
      EXPECT_EQ(fc.slave_boot_failures, 0u);
      EXPECT_EQ(fc.episodes, 0u);
      EXPECT_EQ(vr.controller().master().counters().resets, 2u);
      EXPECT_TRUE(vr.controller().running());
      EXPECT_LT(rmse, 1.0);
      EXPECT_EQ(tool.value(c.node, c.index, c.sub), c.configured) << "read back after the boot";
    }
  }
}

// The rig's own heartbeat of 1000 ms: consumed with 2050 ms (0x1016), a start grace of 3 s - the slaves
// report Operational only with their next heartbeat, up to a second after the start, which is no fault.
TEST(RigBoot, SlowHeartbeatsGiveALongerConsumerTimeAndStartGrace) {
  const auto path = writeTemp("rig.ini", rigText({{"heartbeat_ms = 100       ; 0x1017", "heartbeat_ms = 1000 ; 0x1017"},
                                                  {"heartbeat_ms = 100\nmaster", "heartbeat_ms = 1000\nmaster"}}));
  std::vector<std::string> log;
  rig::VirtualRig vr(controllerFromRig(path, &log), emulator());
  Tool tool(vr);
  vr.start();
  vr.runFor(6.0);
  EXPECT_EQ(tool.read32(1, 0x1016, 1), 0x00020000u | 2050u);
  EXPECT_EQ(tool.read32(1, 0x1016, 2), 0x00030000u | 2050u);
  EXPECT_EQ(vr.controller().master().startGraceUs(2), 3'000'000);
  const auto fc = vr.controller().faultCounters();
  EXPECT_EQ(fc.slave_boots, 2u);
  EXPECT_EQ(fc.episodes, 0u) << "no slave taken for down while its Operational heartbeat is due";
  EXPECT_EQ(vr.controller().master().counters().starts, 2u) << "one start each";
  EXPECT_TRUE(vr.controller().running());
  EXPECT_LT(trackingRmse(vr.records(), 3.0), 1.0);
}

// 0x1F81 bit 4, keep alive: slaves another master left Operational, their heartbeats live, are neither
// reset nor configured at the controller's start (their identity is checked) - not one NMT reset on the
// bus for them - and the loop runs on them; left in Pre-operational they are reset and booted as any other.
TEST(RigBoot, KeptAliveSlavesThatRunAreNotResetAtTheControllersStart) {
  const auto path = writeTemp(
      "rig.ini", rigText({{"mandatory = yes          ; 0x1F81", "keep_alive = yes\nmandatory = yes ; 0x1F81"},
                          {"boot = yes\nmandatory = yes\n", "boot = yes\nmandatory = yes\nkeep_alive = yes\n"}}));
  for (bool operational : {true, false}) {
    SCOPED_TRACE(operational ? "Operational" : "Pre-operational");
    std::vector<std::string> log;
    rig::VirtualRig vr(controllerFromRig(path, &log), emulator());
    Tool tool(vr);
    std::vector<std::string> nmt;
    vr.addTap([&](const Frame& f, canopen::TimeUs) {
      if (f.id == 0x000 && f.len == 2) nmt.push_back(canopen::formatFrame(f));
    });
    vr.startEmulator();
    if (operational) {
      const std::uint8_t all[2] = {0x01, 0x00};
      tool.port.send(canopen::makeFrame(0x000, 2, all));
    }
    vr.runFor(0.3);  // their heartbeats go on
    nmt.clear();
    vr.startController();
    vr.runFor(4.0);
    const auto& mc = vr.controller().master().counters();
    auto resets = [&](const char* id) {
      return std::count(nmt.begin(), nmt.end(), std::string("000#82") + id) +
             std::count(nmt.begin(), nmt.end(), std::string("000#81") + id);
    };
    EXPECT_TRUE(vr.controller().running());
    EXPECT_LT(trackingRmse(vr.records(), 1.0), 1.0);
    if (operational) {
      EXPECT_EQ(resets("02") + resets("03") + resets("00"), 0) << "no reset on the bus";
      EXPECT_EQ(mc.kept_alive, 2u);
      EXPECT_EQ(mc.resets, 0u);
      EXPECT_EQ(mc.boots, 0u) << "not configured again";
      EXPECT_EQ(std::count_if(log.begin(), log.end(),
                              [](const std::string& l) { return l.find("kept alive") != std::string::npos; }),
                2);
    } else {
      EXPECT_EQ(resets("02"), 1);
      EXPECT_EQ(resets("03"), 1);
      EXPECT_EQ(mc.boots, 2u);
    }
  }
}
