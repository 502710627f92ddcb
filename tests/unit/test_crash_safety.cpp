// Nothing lost on a crash, and the soak (docs/RELIABILITY.md): readers tolerate a log cut off in its
// last line, atomic writes leave no temporary and never a half-written file, the rig's candump log is
// on disk while the run goes on, and a short soak of the rig with random faults passes.
// tests/e2e/kill_test.sh kills real processes; this file checks the pieces in-process.
#include <gtest/gtest.h>

#include <dirent.h>
#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "canopen/candump_log.hpp"
#include "io/measurement.hpp"
#include "rig/fault_rig.hpp"
#include "rig/virtual_rig.hpp"

using namespace pamc;

namespace {

const std::string kOd = std::string(PAMC_SOURCE_DIR) + "/od";

std::vector<std::string> listDir(const std::string& dir) {
  std::vector<std::string> names;
  if (DIR* d = ::opendir(dir.c_str())) {
    while (auto* e = ::readdir(d)) {
      const std::string n = e->d_name;
      if (n != "." && n != "..") names.push_back(n);
    }
    ::closedir(d);
  }
  return names;
}

std::string readAll(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

}  // namespace

TEST(CandumpLog, CutOffLastLineIsIgnoredWithWarning) {
  using canopen::readCandumpLog;
  std::vector<std::string> warning;
  {
    // Cut in its data: it would parse as a 1-byte frame, so it is dropped whatever it holds.
    std::istringstream in("(1.000000) vcan0 080#\n(1.000100) vcan0 182#10");
    const auto log = readCandumpLog(in, "run.log", &warning);
    ASSERT_EQ(log.size(), 1u);
    EXPECT_EQ(log[0].frame.id, 0x80u);
    EXPECT_EQ(warning, std::vector<std::string>{"run.log:2: truncated last line ignored (no newline at the end)"});
  }
  {
    std::istringstream in("(1.000000) vcan0 080#\n(1.000100) vc");  // cut before the frame
    warning.clear();
    EXPECT_EQ(readCandumpLog(in, "run.log", &warning).size(), 1u);
    EXPECT_EQ(warning.size(), 1u);
  }
  {
    std::istringstream in("(1.000000) vcan0 080#\n(1.000100) vcan0 182#10203040\n");  // whole
    warning.clear();
    EXPECT_EQ(readCandumpLog(in, "run.log", &warning).size(), 2u);
    EXPECT_TRUE(warning.empty());
  }
  // A bad line that is not the last one is still an error: it was written whole.
  std::istringstream bad("(1.000000) vcan0 080#\n(1.000100) vcan0 18#10\n(1.000200) vcan0 080#");
  EXPECT_THROW(readCandumpLog(bad, "run.log", &warning), std::runtime_error);
}

TEST(AtomicWrite, ReplacesWholeAndLeavesNoTemporary) {
  const std::string dir = ::testing::TempDir() + "/pamc_atomic_dir";
  ::mkdir(dir.c_str(), 0755);
  for (const auto& n : listDir(dir)) std::remove((dir + "/" + n).c_str());
  const std::string path = dir + "/m.json";
  io::writeFileAtomic(path, "first\n");
  EXPECT_EQ(readAll(path), "first\n");
  const std::string big(1 << 20, 'x');  // replaced by a bigger file: whole or not at all
  io::writeFileAtomic(path, big);
  EXPECT_EQ(readAll(path), big);
  io::writeFileAtomic(path, "third\n");
  EXPECT_EQ(readAll(path), "third\n");
  EXPECT_EQ(listDir(dir), std::vector<std::string>{"m.json"});
  // Permissions as for any new file (0666 less the umask), not those of a private temporary.
  const mode_t mask = ::umask(0);
  ::umask(mask);
  struct stat st {};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0666 & ~mask);
  EXPECT_THROW(io::writeFileAtomic(dir + "/no-such-dir/x.json", "x"), std::runtime_error);
  EXPECT_EQ(listDir(dir), std::vector<std::string>{"m.json"});
  std::remove(path.c_str());
}

// The live rig: while it runs, the candump log on disk is complete up to the last cycle or two.
TEST(VirtualRig, CandumpLogIsOnDiskWhileTheRunGoesOn) {
  const std::string log = ::testing::TempDir() + "/pamc_live.log";
  nodes::ControllerNodeConfig c;
  c.eds_path = kOd + "/controller.eds";
  c.kind = static_cast<int>(control::Kind::PI);
  c.gains_from_config = true;
  c.has_trajectory = true;
  c.trajectory = control::Trajectory::constant(15.0);
  c.preroll_s = 0.05;
  nodes::EmulatorConfig e;
  e.sensor_eds = kOd + "/sensor.eds";
  e.valve_eds = kOd + "/valve.eds";
  rig::VirtualRigHooks hooks;
  hooks.realtime = true;
  const canopen::TimeUs epoch = 1700000000000000;
  int checks = 0;
  canopen::TimeUs worst_gap = 0;
  hooks.on_step = [&](canopen::TimeUs now) {
    if (now % 20'000 != 0) return true;
    // The log as a crash would leave it now: every line whole, the last frame within 2 ms of now.
    std::ifstream in(log);
    std::vector<std::string> warning;
    const auto frames = canopen::readCandumpLog(in, log, &warning);
    EXPECT_TRUE(warning.empty()) << warning.front();
    if (!frames.empty()) worst_gap = std::max(worst_gap, epoch + now - frames.back().unix_time_us);
    ++checks;
    return true;
  };
  const auto r = rig::runVirtualRig(c, e, 0.1, log, epoch, 0, hooks);
  EXPECT_GE(checks, 5);
  EXPECT_LE(worst_gap, 2000);
  EXPECT_GE(r.records.size(), 99u);
  std::remove(log.c_str());
}

// A short soak: faults of the whole catalogue at random times, every one checked.
TEST(Soak, ShortRunWithRandomFaultsPasses) {
  rig::SoakOptions o;
  o.od_dir = kOd;
  o.kind = control::Kind::PI;  // PI + AMC does not pass yet: docs/RELIABILITY.md, "Soak"
  o.hours = 0.05;
  o.report_s = 60;
  o.gap_min_s = 2;
  o.gap_max_s = 5;
  const auto r = rig::runSoak(o);
  EXPECT_TRUE(r.passed()) << rig::soakReport(o, r);
  EXPECT_EQ(r.intervals.size(), 3u);
  EXPECT_GE(r.faults, 5u);
  EXPECT_GE(r.reacted, 1u);
  EXPECT_EQ(r.back, r.checked);
  EXPECT_GT(r.baseline_rmse, 0.0);
  std::uint64_t cycles = 0, lost = 0;
  for (const auto& i : r.intervals) cycles += i.cycles, lost += i.lost_clean;
  EXPECT_EQ(lost, 0u);
  EXPECT_GT(cycles, 170'000u);  // 180 s of SYNCs less those lost to SYNC faults
  EXPECT_LE(r.heap_growth_bytes, o.heap_growth_limit);
}
