// The emulator's sensor device (od/sensor.eds, CiA 406): reports the position the emulator measures in
// 0x6004 and sends it in its TPDO. Its frames pass through its faults: silent from a time on (for a
// while), position PDOs dropped at random or late by whole cycles; at run time (Injection) also
// silent, position PDOs delayed on the wire, duplicated, dropped in a burst or with a wrong length,
// heartbeats with a wrong length, a reboot.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <random>

#include "canopen/node.hpp"
#include "nodes/emulator_config.hpp"

namespace pamc::nodes {

// The frames held back by a delay on the wire, in order (one delay for all, so a FIFO).
class DelayLine {
 public:
  void push(const canopen::Frame& f, canopen::TimeUs due);    // dropped when full
  void release(canopen::Transport& to, canopen::TimeUs now);  // sends those due by now
  canopen::TimeUs nextDue() const { return count_ > 0 ? frames_[head_].due : canopen::kNever; }
  void clear() { count_ = 0; }

 private:
  struct Delayed {
    canopen::Frame frame;
    canopen::TimeUs due;
  };
  std::array<Delayed, 64> frames_{};
  std::size_t head_ = 0, count_ = 0;
};

// The node is the sensor's own transport (send): every frame it sends passes its faults first.
class EmulatedSensor : private canopen::Transport {
 public:
  // id: its node-ID (0: the EDS's).
  EmulatedSensor(const EmulatorConfig& cfg, canopen::Transport& bus, Injection& inj, std::uint8_t id);
  void start(canopen::TimeUs now);

  // At SYNC k (time t): the position measured over the cycle that just ended, in counts; 0x6004 gets
  // it late_pdo_cycles cycles late.
  void measured(std::uint64_t k, double t, std::int32_t counts);
  // The time is now: sends the delayed frames due by then. Before onFrame and advance, and while silent.
  void tick(canopen::TimeUs now);
  void onFrame(const canopen::Frame& f, canopen::TimeUs now);  // unless silent
  void advance(canopen::TimeUs now);
  canopen::TimeUs nextDeadline() const;

  canopen::Node& node() { return *node_; }
  bool silent() const;
  // Off (silent and deaf) for downtime, then back through an NMT reset: boot-up and Pre-operational.
  void reboot(canopen::TimeUs downtime_us);
  std::uint64_t pdosDropped() const { return dropped_; }

 private:
  bool send(const canopen::Frame& f) override;
  bool sendPosition(canopen::Frame g);
  bool dropPosition();

  const EmulatorConfig& cfg_;
  canopen::Transport& bus_;
  Injection& inj_;
  std::unique_ptr<canopen::Node> node_;
  canopen::Ref<std::int32_t> position_{nullptr};
  std::uint32_t pdo_cob_ = 0x182;
  std::array<std::int32_t, 256> late_{};  // the positions of the last SYNCs, by SYNC count
  double t_ = 0;                          // the time of the last SYNC
  canopen::TimeUs now_us_ = 0;
  std::uint64_t dropped_ = 0;
  std::mt19937_64 rng_;
  DelayLine delayed_;
  bool rebooting_ = false;
  canopen::TimeUs reboot_until_ = 0;
};

}  // namespace pamc::nodes
