// candump log -> measurement rows through the EDS files, with the rig's timing.
#include <gtest/gtest.h>

#include <cmath>

#include "nodes/decoder.hpp"
#include "nodes/monitor.hpp"

using namespace pamc;

namespace {
const std::string kOd = std::string(PAMC_SOURCE_DIR) + "/od";

canopen::CandumpRecord rec(double t, std::uint32_t id, std::vector<std::uint8_t> data) {
  canopen::CandumpRecord r;
  r.unix_time_us = static_cast<canopen::TimeUs>(std::llround(t * 1e6));
  r.interface = "vcan0";
  r.frame.id = id;
  r.frame.len = static_cast<std::uint8_t>(data.size());
  for (size_t i = 0; i < data.size(); ++i) r.frame.data[i] = data[i];
  return r;
}
std::vector<std::uint8_t> i32(std::int32_t v) {
  return {static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 8), static_cast<std::uint8_t>(v >> 16),
          static_cast<std::uint8_t>(v >> 24)};
}
std::vector<std::uint8_t> i16(std::int16_t v) {
  return {static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 8)};
}
}  // namespace

TEST(Decoder, MappingsComeFromTheEdsFiles) {
  const auto d = nodes::loadBusDictionary({kOd});
  ASSERT_TRUE(d.pdos.count(0x182));
  EXPECT_EQ(d.pdos.at(0x182).fields.at(0).role, "y");
  ASSERT_TRUE(d.pdos.count(0x203));
  EXPECT_EQ(d.pdos.at(0x203).fields.at(0).role, "u");
  ASSERT_TRUE(d.pdos.count(0x183));
  EXPECT_EQ(d.pdos.at(0x183).fields.at(0).role, "p");
  EXPECT_EQ(d.sync_cob, 0x80u);
  EXPECT_DOUBLE_EQ(d.sync_period_s, 1e-3);
}

// Cycle k: SYNC, the sensor's position, the valve's pressure, the controller's command. The valve
// latches a command at the next SYNC and holds it over the following cycle, so the row of cycle k
// carries as u the command sent in cycle k-2.
TEST(Decoder, RowsCarryTheCommandInEffectWhenThePositionWasTaken) {
  const auto d = nodes::loadBusDictionary({kOd});
  std::vector<canopen::CandumpRecord> log;
  const std::int16_t cmd[] = {16384, 20000, 24000, 28000, 32000, 30000};
  for (int k = 0; k < 6; ++k) {
    const double t = 1.0 + k * 1e-3;
    log.push_back(rec(t, 0x80, {}));
    log.push_back(rec(t + 1e-4, 0x182, i32(1000 * (k + 1))));  // y = k+1 mm
    log.push_back(rec(t + 2e-4, 0x183, i16(3277)));            // 1 bar
    log.push_back(rec(t + 3e-4, 0x203, i16(cmd[k])));
  }
  log.push_back(rec(1.006, 0x80, {}));
  log.push_back(rec(1.0061, 0x701, {0x05}));  // heartbeat: expected traffic, not unknown
  log.push_back(rec(1.0062, 0x123, {1, 2}));  // unknown COB-ID
  log.push_back(rec(1.0063, 0x182, {1, 2}));  // wrong length
  const auto run = nodes::decodeCandump(log, d);
  ASSERT_EQ(run.columns[0], "t");
  ASSERT_EQ(run.columns[1], "u");
  ASSERT_EQ(run.columns[2], "y");
  ASSERT_GE(run.rows.size(), 3u);
  // First complete row: cycle 2 (y = 3 mm) with the command of cycle 0.
  EXPECT_DOUBLE_EQ(run.rows[0][2], 3.0);
  EXPECT_NEAR(run.rows[0][1], cmd[0] * 10.0 / 32767.0 - 5.0, 1e-12);
  EXPECT_DOUBLE_EQ(run.rows[1][2], 4.0);
  EXPECT_NEAR(run.rows[1][1], cmd[1] * 10.0 / 32767.0 - 5.0, 1e-12);
  EXPECT_NEAR(run.rows[0][3], 3277 * 10.0 / 32767.0, 1e-12);
  EXPECT_NEAR(run.rows[1][0] - run.rows[0][0], 1e-3, 1e-12);
  EXPECT_EQ(run.unknown, 1u);
  EXPECT_EQ(run.bad_length, 1u);
}

// A lost position PDO: the cycle keeps its row with the last position, and t stays SYNC index x period.
TEST(Decoder, LostPositionHoldsTheLastValueAndKeepsTheTimeBase) {
  const auto d = nodes::loadBusDictionary({kOd});
  std::vector<canopen::CandumpRecord> log;
  for (int k = 0; k < 8; ++k) {
    const double t = 1.0 + k * 1e-3;
    log.push_back(rec(t, 0x80, {}));
    if (k != 4) log.push_back(rec(t + 1e-4, 0x182, i32(1000 * (k + 1))));
    log.push_back(rec(t + 3e-4, 0x203, i16(20000)));
  }
  log.push_back(rec(1.008, 0x80, {}));
  const auto run = nodes::decodeCandump(log, d);
  EXPECT_EQ(run.held, 1u);
  ASSERT_EQ(run.rows.size(), 6u);  // cycles 2..7
  for (size_t i = 0; i < run.rows.size(); ++i) EXPECT_NEAR(run.rows[i][0], i * 1e-3, 1e-12);
  EXPECT_DOUBLE_EQ(run.rows[2][2], 4.0);  // cycle 4 lost: holds cycle 3's 4 mm
  EXPECT_DOUBLE_EQ(run.rows[3][2], 6.0);
  // The pressure never came: its column is left out rather than written empty.
  EXPECT_EQ(run.columns, (std::vector<std::string>{"t", "u", "y", "t_log"}));
}

// The valve's first pressure PDO comes two cycles after the sensor's first position: the decoded run
// starts at the first complete row (no empty cells, which a measurement file may not have), at t = 0.
TEST(Decoder, RunStartsWhereEveryColumnHasAValue) {
  const auto d = nodes::loadBusDictionary({kOd});
  std::vector<canopen::CandumpRecord> log;
  for (int k = 0; k < 8; ++k) {
    const double t = 1.0 + k * 1e-3;
    log.push_back(rec(t, 0x80, {}));
    log.push_back(rec(t + 1e-4, 0x182, i32(1000 * (k + 1))));
    if (k >= 4) log.push_back(rec(t + 2e-4, 0x183, i16(3277)));
    log.push_back(rec(t + 3e-4, 0x203, i16(16384)));
  }
  log.push_back(rec(1.008, 0x80, {}));
  const auto run = nodes::decodeCandump(log, d);
  ASSERT_EQ(run.columns.at(3), "p");
  ASSERT_FALSE(run.rows.empty());
  for (const auto& r : run.rows)
    for (double v : r) EXPECT_FALSE(std::isnan(v));
  EXPECT_DOUBLE_EQ(run.rows[0][0], 0.0);
  EXPECT_DOUBLE_EQ(run.rows[0][2], 5.0);  // cycle 4, the first with a pressure
  EXPECT_NEAR(run.rows[1][0] - run.rows[0][0], 1e-3, 1e-12);
}

TEST(Monitor, ShowsStatesValuesAndEmergencies) {
  nodes::Monitor m(nodes::loadBusDictionary({kOd}));
  canopen::Frame hb;
  hb.id = 0x702;
  hb.len = 1;
  hb.data[0] = 0x05;
  m.feed(hb, 0.1);
  canopen::Frame pos;
  pos.id = 0x182;
  pos.len = 4;
  const auto v = i32(12345);
  for (int i = 0; i < 4; ++i) pos.data[i] = v[static_cast<size_t>(i)];
  m.feed(pos, 0.2);
  canopen::Frame em;
  em.id = 0x81;
  em.len = 8;
  em.data[0] = 0x50;
  em.data[1] = 0x82;
  m.feed(em, 0.3);
  const auto s = m.render(0.5);
  EXPECT_NE(s.find("sensor       operational"), std::string::npos) << s;
  EXPECT_NE(s.find("12.3450 mm"), std::string::npos) << s;
  EXPECT_NE(s.find("EMCY 0x8250"), std::string::npos) << s;
  EXPECT_EQ(m.emcys(), 1u);
}
