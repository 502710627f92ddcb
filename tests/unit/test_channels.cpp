// Several channels on one controller node (nodes/controller_node.hpp, od/rigs/four_muscles.ini): four
// muscles boot and track on one 1 Mbit/s bus within 90 % of it, each channel as one muscle alone; a
// fault of one channel stops that channel only - with its joint partner, or every channel with
// faults = all - with an EMCY naming it; rig files of several channels that cannot work are refused
// with the line.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "../common/rig_text.hpp"
#include "canopen/frame_bits.hpp"
#include "nodes/rig_file.hpp"
#include "plant/plant.hpp"
#include "rig/rig_emulator.hpp"
#include "rig/virtual_rig.hpp"

using namespace pamc;

namespace {

using test::kOd;
using test::writeTemp;

// od/rigs/four_muscles.ini with lines replaced or added, its EDS paths made absolute.
std::string fourMuscles(const test::Edits& edits = {}) { return test::shippedRig("four_muscles.ini", edits); }

nodes::ControllerNodeConfig controllerOf(const nodes::RigFile& rig, std::vector<std::string>* log = nullptr) {
  return test::rigController(rig, log);
}

nodes::EmulatorConfig emulatorOf(const nodes::RigFile& rig) { return rig::emulatorOf(rig, test::pamcEmulator()); }

struct ChannelTrack {
  double acc = 0, max = 0;
  int n = 0;
  double rmse() const { return n ? std::sqrt(acc / n) : INFINITY; }
};

// Tracking per channel from from_s to to_s of trajectory time, faulted cycles included (a channel in its
// safe state does not track).
std::vector<ChannelTrack> tracking(const std::vector<nodes::CycleRecord>& recs, std::size_t channels, double from_s,
                                   double to_s = 1e9) {
  std::vector<ChannelTrack> t(channels);
  for (const auto& r : recs) {
    if (r.t < from_s || r.t > to_s || r.channel >= channels) continue;
    auto& c = t[r.channel];
    const double e = r.y - r.yd;
    c.acc += e * e, c.max = std::max(c.max, std::fabs(e)), ++c.n;
  }
  return t;
}

// The EMCYs the controller sent: error code and the channel it names (byte 3 of the manufacturer bytes).
struct Emcy {
  std::uint16_t code;
  std::uint8_t fault, detail, channel;
};

}  // namespace

TEST(Channels, FourMusclesBootAndTrackOnOneBusAsOneMuscleAlone) {
  const auto rig_file = nodes::readRigFile(writeTemp("four.ini", fourMuscles()));
  ASSERT_EQ(rig_file.channels.size(), 4u);
  std::vector<std::string> log;
  rig::VirtualRig rig(controllerOf(rig_file, &log), emulatorOf(rig_file));
  canopen::BusLoadMeter meter;
  canopen::TimeUs first = -1, last = 0;
  rig.addTap([&](const canopen::Frame& f, canopen::TimeUs t) {
    meter.add(f);
    if (first < 0) first = t;
    last = t;
  });
  rig.start();
  rig.runFor(20.5);
  int configured = 0;
  for (const auto& l : log) configured += l.find("configuration written and read back") != std::string::npos;
  EXPECT_EQ(configured, 5) << "four encoders and the valve module booted";
  const auto four = tracking(rig.records(), 4, 5.0);
  // The one-muscle rig, the same trajectory and plant.
  const auto one_file = nodes::readRigFile(kOd + "rigs/default.ini");
  rig::VirtualRig one(controllerOf(one_file), emulatorOf(one_file));
  one.start();
  one.runFor(20.5);
  const auto alone = tracking(one.records(), 1, 5.0);
  ASSERT_GT(alone[0].n, 10000);
  for (std::size_t c = 0; c < 4; ++c) {
    EXPECT_GT(four[c].n, 10000) << "channel " << c + 1;
    EXPECT_NEAR(four[c].rmse(), alone[0].rmse(), 0.1 * alone[0].rmse()) << "channel " << c + 1;
  }
  const double load = meter.load(static_cast<double>(last - first) * 1e-6, rig_file.bitrate);
  EXPECT_LT(load, 0.90) << "four muscles at 1 kHz within 90 % of 1 Mbit/s";
  EXPECT_GT(load, 0.40) << "SYNC + 6 frames of the cycle per millisecond";
  EXPECT_EQ(rig.controller().faultCounters().episodes, 0u);
}

namespace {

// Four muscles with the sensor of channel `faulty` (0-based) going silent at 8 s of bus time for 2 s.
struct SilentSensorRun {
  explicit SilentSensorRun(const std::string& text, std::size_t faulty) {
    const auto rf = nodes::readRigFile(text);
    auto e = emulatorOf(rf);
    e.fault_channel = faulty;
    e.sensor_silent_at_s = 8.0;
    e.sensor_silent_for_s = 2.0;
    rig = std::make_unique<rig::VirtualRig>(controllerOf(rf), e);
    rig->addTap([this](const canopen::Frame& f, canopen::TimeUs) {
      if (f.id == 0x81 && f.len == 8) emcy.push_back(Emcy{canopen::getU16(f.data), f.data[3], f.data[4], f.data[5]});
    });
    rig->start();
    rig->runFor(9.0);  // 8.0 + 1 s: the fault is on
    for (std::size_t c = 0; c < 4; ++c) during.push_back(rig->controller().channelFault(c));
    safe_volts = nodes::pd::valveVolts(rig->controller().safeCommand());
    for (std::size_t c = 0; c < 4; ++c) volts.push_back(rig->emulator().valveVolts(c));
    rig->runFor(6.0);  // back at 10 s; recovered 0.5 s later
    for (std::size_t c = 0; c < 4; ++c) after.push_back(rig->controller().channelFault(c));
  }
  bool named(nodes::Fault f, std::uint8_t channel) const {
    for (const auto& e : emcy)
      if (e.fault == static_cast<std::uint8_t>(f) && e.channel == channel) return true;
    return false;
  }
  std::unique_ptr<rig::VirtualRig> rig;
  std::vector<Emcy> emcy;
  std::vector<nodes::Fault> during, after;
  std::vector<double> volts;
  double safe_volts = 0;
};

}  // namespace

TEST(Channels, ASilentSensorStopsItsChannelOnly) {
  SilentSensorRun r(writeTemp("four.ini", fourMuscles()), 1);
  EXPECT_NE(r.during[1], nodes::Fault::None);
  EXPECT_NEAR(r.volts[1], r.safe_volts, 1e-3) << "channel 2's valve at the safe value";
  for (std::size_t c : {0u, 2u, 3u}) {
    EXPECT_EQ(r.during[c], nodes::Fault::None) << "channel " << c + 1;
    EXPECT_GT(r.volts[c], r.safe_volts + 0.5) << "channel " << c + 1 << " still driven";
  }
  EXPECT_TRUE(r.named(nodes::Fault::PositionMissing, 2)) << "an EMCY naming channel 2";
  for (const auto& e : r.emcy) EXPECT_EQ(e.channel, 2) << "EMCY 0x" << std::hex << e.code << " of another channel";
  // The others tracked through it as before; channel 2 came back.
  const auto t = tracking(r.rig->records(), 4, 5.0);
  for (std::size_t c : {0u, 2u, 3u}) EXPECT_LT(t[c].max, 1.5) << "channel " << c + 1;
  for (std::size_t c = 0; c < 4; ++c) EXPECT_EQ(r.after[c], nodes::Fault::None) << "channel " << c + 1;
}

TEST(Channels, AJointPartnerGoesToItsSafeValueWithIt) {
  const auto text = fourMuscles({{"feedback = 0x6401:01", "feedback = 0x6401:01\npartner = 2"},
                                 {"feedback = 0x6401:02", "feedback = 0x6401:02\npartner = 1"}});
  SilentSensorRun r(writeTemp("pair.ini", text), 0);
  EXPECT_NE(r.during[0], nodes::Fault::None);
  EXPECT_EQ(r.during[1], nodes::Fault::OtherChannel) << "channel 2 follows its partner";
  EXPECT_NEAR(r.volts[0], r.safe_volts, 1e-3);
  EXPECT_NEAR(r.volts[1], r.safe_volts, 1e-3);
  EXPECT_EQ(r.during[2], nodes::Fault::None);
  EXPECT_EQ(r.during[3], nodes::Fault::None);
  EXPECT_TRUE(r.named(nodes::Fault::PositionMissing, 1));
  EXPECT_TRUE(r.named(nodes::Fault::OtherChannel, 2));
  for (const auto& e : r.emcy) {
    if (e.fault == static_cast<std::uint8_t>(nodes::Fault::OtherChannel)) {
      EXPECT_EQ(e.detail, 1) << "whose fault it follows";
    }
  }
  for (std::size_t c = 0; c < 4; ++c) EXPECT_EQ(r.after[c], nodes::Fault::None) << "channel " << c + 1 << " recovered";
}

TEST(Channels, WithFaultsAllEveryChannelGoesToItsSafeValue) {
  SilentSensorRun r(writeTemp("all.ini", fourMuscles({{"faults = channel", "faults = all"}})), 2);
  EXPECT_EQ(r.during[2], nodes::Fault::PositionMissing);
  for (std::size_t c : {0u, 1u, 3u}) {
    EXPECT_EQ(r.during[c], nodes::Fault::OtherChannel) << "channel " << c + 1;
    EXPECT_NEAR(r.volts[c], r.safe_volts, 1e-3) << "channel " << c + 1;
  }
  for (std::size_t c = 0; c < 4; ++c) EXPECT_EQ(r.after[c], nodes::Fault::None) << "channel " << c + 1 << " recovered";
}

TEST(Channels, ARigFileOfSeveralChannelsThatCannotWorkIsRefusedWithItsLine) {
  struct Case {
    std::vector<std::pair<std::string, std::string>> edits;
    std::string expect;
  };
  const std::vector<Case> cases = {
      {{{"sensor = enc2", "sensor = enc9"}}, "sensor 'enc9': no [slave.enc9] section"},
      {{{"feedback = 0x6401:01", "feedback = 0x6401:01\npartner = 2"}}, "channel 2 does not name channel 1 back"},
      {{{"feedback = 0x6401:01", "feedback = 0x6401:01\npartner = 1"}}, "a channel is not its own partner"},
      {{{"sensor = enc2", "sensor = io"}}, "its sensor and valve are one slave"},
      {{{"faults = channel", "faults = some"}}, "faults 'some' is not channel or all"},
      {{{"feedback = 0x6401:03", "feedback = 0x6401:03\ncontroller = fuzzy"}}, "controller: "},
      {{{"feedback = 0x6401:03", "feedback = 0x6401:03\ntrajectory = zigzag:1"}}, "trajectory: "},
      {{{"[channel.1]", "[sensor]\n[channel.1]"}}, "write one form"},
      {{{"command = 0x6411:02", "command = 0x6411:05"}}, "has no object 0x6411:05"},
      {{{"position = 0x6004:00\nvalve = io\ncommand = 0x6411:02",
         "position = 0x6004:00\nvalve = io\ncommand = 0x6411:02\nbogus = 1"}},
       "unknown key 'bogus' in [channel.2]"},
      {{{"feedback = 0x6401:04", "feedback = 0x6401:04\n[channel.9]\nsensor = enc1"}},
       ""},  // beyond the numbered run: unused
  };
  for (const auto& c : cases) {
    const std::string path = writeTemp("rig.ini", fourMuscles(c.edits));
    if (c.expect.empty()) {
      EXPECT_NO_THROW((void)nodes::readRigFile(path));
      continue;
    }
    try {
      (void)nodes::readRigFile(path);
      ADD_FAILURE() << "accepted: " << c.expect;
    } catch (const nodes::RigError& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find(c.expect), std::string::npos) << m;
      EXPECT_EQ(m.find('\n'), std::string::npos) << m;
      EXPECT_EQ(m.rfind(path, 0), 0u) << m;
    }
  }
}

TEST(Channels, TheOneMuscleFormAndTheFormOfChannelsMakeTheSameNode) {
  // od/rigs/default.ini (slaves and a channel) and the same rig in the one-muscle form: the same
  // dictionary values, the same channel.
  const auto channels = nodes::readRigFile(kOd + "rigs/default.ini");
  const auto one = nodes::readRigFile(writeTemp("one.ini", test::oneMuscleRig()));
  EXPECT_TRUE(one.one_muscle_form);
  EXPECT_FALSE(channels.one_muscle_form);
  EXPECT_EQ(nodes::masterValues(channels), nodes::masterValues(one));
  ASSERT_EQ(channels.channels.size(), 1u);
  ASSERT_EQ(one.channels.size(), 1u);
  EXPECT_EQ(channels.channels[0].cfg.layout.sensor_cob, one.channels[0].cfg.layout.sensor_cob);
  EXPECT_EQ(channels.channels[0].cfg.layout.feedback_cob, one.channels[0].cfg.layout.feedback_cob);
}

namespace {

// od/rigs/antagonistic.ini with edits, on the in-process bus for `seconds` of trajectory.
struct JointRun {
  JointRun(const std::string& path, double seconds, control::Kind kind = control::Kind::PI, double silent_at = -1) {
    rf = nodes::readRigFile(path);
    auto c = controllerOf(rf);
    c.kind = static_cast<int>(kind);
    auto e = emulatorOf(rf);
    e.sensor_silent_at_s = silent_at;
    e.sensor_silent_for_s = 1.0;
    rig = std::make_unique<rig::VirtualRig>(c, e);
    rig->start();
    for (double t = 0; t < seconds + 0.5; t += 1e-3) {
      rig->step();
      tension += rig->emulator().joint(0).tensionN(), ++n;
      if (silent_at >= 0 && std::fabs(rig->now() * 1e-6 - (silent_at + 0.5)) < 0.5e-3)
        for (std::size_t ch = 0; ch < 2; ++ch) during.push_back(rig->controller().channelFault(ch));
    }
  }
  // The angle's tracking from the flexor's records (y = rest + lever x angle) [deg].
  ChannelTrack angle(double from_s) const {
    auto t = tracking(rig->records(), 2, from_s)[rf.joints[0].flexor];
    const double k = 180.0 / M_PI / rf.joints[0].lever_mm;
    t.acc *= k * k, t.max *= k;
    return t;
  }
  nodes::RigFile rf;
  std::unique_ptr<rig::VirtualRig> rig;
  double tension = 0;
  long n = 0;
  std::vector<nodes::Fault> during;
};

std::string antagonistic(const test::Edits& edits = {}) { return test::shippedRig("antagonistic.ini", edits); }

}  // namespace

// Two muscles of the physics plant on one joint (a 25 mm lever, a cable over the pulley), the angle
// from one encoder: the joint tracks the rig file's +-15 deg triangle with each muscle's own PI - and
// with each muscle's own AMC (its model and UKF) - the muscles moving against each other.
TEST(Joint, AnAntagonisticPairTracksAnAngleTriangle) {
  for (auto kind : {control::Kind::PI, control::Kind::PiAmc}) {
    JointRun r(writeTemp("joint.ini", antagonistic()), 25.0, kind);
    const auto a = r.angle(5.0);
    EXPECT_GT(a.n, 15000);
    EXPECT_LT(a.rmse(), 1.0) << control::toString(kind) << ": angle RMSE [deg]";
    EXPECT_LT(a.max, 3.0) << control::toString(kind) << ": angle max error [deg]";
    EXPECT_EQ(r.rig->controller().faultCounters().episodes, 0u);
    // The flexor contracts as the angle grows, the extensor lengthens: their positions move against each other.
    double s1 = 0, s2 = 0, s12 = 0, s11 = 0, s22 = 0;
    int m = 0;
    std::vector<double> y[2];
    for (const auto& x : r.rig->records())
      if (x.t >= 5.0 && x.channel < 2) y[x.channel].push_back(x.y);
    for (std::size_t i = 0; i < std::min(y[0].size(), y[1].size()); ++i, ++m)
      s1 += y[0][i], s2 += y[1][i], s12 += y[0][i] * y[1][i], s11 += y[0][i] * y[0][i], s22 += y[1][i] * y[1][i];
    const double cov = s12 / m - s1 / m * s2 / m;
    const double corr = cov / std::sqrt((s11 / m - s1 / m * s1 / m) * (s22 / m - s2 / m * s2 / m));
    EXPECT_LT(corr, -0.99) << "the two muscles' positions";
  }
}

// Co-contraction: the same angle triangle with more of it on both commands tenses the cable more.
TEST(Joint, CoContractionRaisesTheCableTension) {
  JointRun low(writeTemp("low.ini", antagonistic({{"stiffness_v = 0.5", "stiffness_v = 0"}})), 15.0);
  JointRun high(writeTemp("high.ini", antagonistic({{"stiffness_v = 0.5", "stiffness_v = 1.5"}})), 15.0);
  EXPECT_GT(high.tension / high.n, 1.2 * low.tension / low.n) << "mean cable tension [N]";
  EXPECT_LT(high.angle(5.0).rmse(), 1.0);
}

// The angle encoder falling silent takes both muscles to their safe values.
TEST(Joint, ALostAngleStopsBothMuscles) {
  JointRun r(writeTemp("joint.ini", antagonistic()), 12.0, control::Kind::PI, 8.0);
  ASSERT_EQ(r.during.size(), 2u);
  EXPECT_NE(r.during[0], nodes::Fault::None);
  EXPECT_NE(r.during[1], nodes::Fault::None);
  EXPECT_EQ(r.rig->controller().channelFault(0), nodes::Fault::None) << "recovered after the encoder came back";
}

TEST(Joint, AJointThatCannotWorkIsRefusedWithItsLine) {
  const std::vector<std::pair<std::pair<std::string, std::string>, std::string>> cases = {
      {{"muscles = 1, 2", "muscles = 1, 1"}, "is not two channels"},
      {{"muscles = 1, 2", "muscles = 1, 3"}, "is not two channels"},
      {{"[channel.1]               ; the flexor\n", "[channel.1]\nsensor = angle\n"}, "whose angle and pair say it"},
      {{"lever_mm = 25", "lever_mm = 0"}, "lever_mm 0 is outside"},
      {{"trajectory = triangle:0.05:-15:15", "trajectory = wobble"}, "trajectory: "},
  };
  for (const auto& [edit, expect] : cases) {
    const std::string path = writeTemp("bad.ini", antagonistic({edit}));
    try {
      (void)nodes::readRigFile(path);
      ADD_FAILURE() << "accepted: " << expect;
    } catch (const nodes::RigError& e) {
      EXPECT_NE(std::string(e.what()).find(expect), std::string::npos) << e.what();
    }
  }
}
