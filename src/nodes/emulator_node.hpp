// The plant emulator on the bus: the sensor node (od/sensor.eds, CiA 406) and the valve node
// (od/valve.eds, CiA 401) of the rig, played by one process around the emulator physics.
// Stepped by the SYNCs it receives: on SYNC k the muscle is advanced over (k-1, k] under the valve
// command latched at SYNC k-1, the position is put into 0x6004 (sent in the sensor's TPDO after this
// SYNC) and the pressure into 0x6401:01; then the valve latches the command received during the last
// cycle, which holds over (k, k+1].
// Fault injection: sensor silent from a time on (for a while), position PDOs dropped at random or
// late by whole cycles, a payload step; at run time (inject(), the fault rig) also: either node
// silent, position PDOs delayed on the wire, duplicated, dropped in a burst or with a wrong length,
// sensor heartbeats with a wrong length, a sensor reboot.
// The valve behaves as a CiA 401 output on a communication error: when it is not Operational, its
// SYNC stops (SYNC timeout from its 0x1006, set to the emulator's period) or the controller's
// heartbeat times out (its 0x1016), it outputs its error value 0x6444:01 (0x6443:01 = 1) until it
// is back in order and has latched a fresh command.
#pragma once

#include <array>
#include <atomic>
#include <memory>
#include <random>
#include <string>

#include "canopen/node.hpp"
#include "nodes/process_data.hpp"
#include "plant/plant.hpp"

namespace pamc::nodes {

struct EmulatorConfig {
  std::string sensor_eds = "od/sensor.eds";
  std::string valve_eds = "od/valve.eds";
  // The devices: node-IDs (0: the EDS's), which objects carry the numbers and how they count. The
  // defaults are od/sensor.eds and od/valve.eds; profileDevices() the off-the-shelf kind.
  std::uint8_t sensor_id = 0, valve_id = 0;
  std::uint16_t position_index = 0x6004;
  std::uint8_t position_sub = 0;
  std::uint16_t command_index = 0x6411;
  std::uint8_t command_sub = 1;  // CiA 401: its error mode 0x6443 and error value 0x6444 have the same sub-index
  std::uint16_t pressure_index = 0x6401;
  std::uint8_t pressure_sub = 1;
  pd::Scaling scaling;
  // A CiA 406 encoder (node 16, 5 um steps, asynchronous TPDO) and a CiA 401 analog I/O module (node 32,
  // valve on output 2, pressure on input 2, 0..20000 = full scale, no heartbeat) with their makers'
  // defaults (od/profile/): nothing fits pamc's controller until it configures them (od/rigs/profile.ini).
  static EmulatorConfig profileDevices(const std::string& od_dir);
  void useProfileDevices(const std::string& od_dir);  // the same on this configuration's devices
  plant::PlantConfig plant = plant::PlantConfig::defaults();
  double sensor_silent_at_s = -1;   // < 0: never
  double sensor_silent_for_s = 1e9;
  double drop_pdo_prob = 0.0;       // probability of dropping a position PDO
  int late_pdo_cycles = 0;          // position reported this many cycles late
  double payload_at_s = -1;         // < 0: no payload step
  double payload_N = 40.0;
  std::uint64_t seed = 7;
};

// Faults switched at run time (by the fault rig or a test); they act from the next frame on.
struct Injection {
  bool sensor_silent = false;          // the sensor sends nothing and hears nothing
  bool valve_silent = false;           // the valve sends nothing (it still receives)
  canopen::TimeUs pdo_delay_us = 0;    // position PDOs leave this much later than sent
  bool pdo_duplicate = false;          // every position PDO goes out twice
  int pdo_len = -1;                    // position PDOs with this DLC (-1: as mapped)
  int heartbeat_len = -1;              // sensor heartbeats with this DLC (-1: 1)
  int drop_next = 0;                   // drop this many position PDOs in a row
  double drop_prob = 0.0;              // drop each position PDO with this probability (seeded)
};

class EmulatorNodes : public canopen::BusClient {
 public:
  EmulatorNodes(const EmulatorConfig& cfg, canopen::Transport& transport);
  void start(canopen::TimeUs now);

  void onFrame(const canopen::Frame& f, canopen::TimeUs now) override;
  void advance(canopen::TimeUs now) override;
  canopen::TimeUs nextDeadline() const override;

  canopen::Node& sensor() { return *sensor_; }
  canopen::Node& valve() { return *valve_; }
  const plant::Plant& plant() const { return plant_; }
  // Safe from another thread.
  double time() const { return static_cast<double>(syncs_.load(std::memory_order_relaxed)) * plant_.config().Ts; }
  std::uint64_t pdosDropped() const { return dropped_; }

  Injection& inject() { return inj_; }
  // The sensor goes off (silent and deaf) for downtime, then comes back through an NMT reset: boot-up
  // and Pre-operational, as after a power cycle.
  void rebootSensor(canopen::TimeUs downtime_us);
  // What the valve outputs (0..10 V), whether it is at its error value, and when the output last changed.
  double valveVolts() const { return pd::valveVolts(u_held_); }
  bool valveInError() const { return valve_error_; }
  canopen::TimeUs valveChangedUs() const { return valve_changed_us_; }

 private:
  // Each node's frames pass through here, so faults can silence, thin, delay or corrupt them.
  class FaultyLink : public canopen::Transport {
   public:
    FaultyLink(EmulatorNodes& owner, canopen::Transport& inner, bool sensor)
        : owner_(owner), inner_(inner), sensor_(sensor) {}
    bool send(const canopen::Frame& f) override;

   private:
    EmulatorNodes& owner_;
    canopen::Transport& inner_;
    bool sensor_;
  };
  bool sensorSilent() const;
  // Applies the command or, on a communication error, the error value; notes when the output changes.
  void updateValve(canopen::TimeUs now);
  void releaseDelayed(canopen::TimeUs now);

  EmulatorConfig cfg_;
  canopen::Transport& bus_;
  FaultyLink sensor_link_, valve_link_;
  std::unique_ptr<canopen::Node> sensor_, valve_;
  plant::Plant plant_;
  canopen::Ref<std::int32_t> position_{nullptr};
  canopen::Ref<std::int16_t> pressure_{nullptr};
  canopen::Ref<std::int16_t> command_{nullptr};
  std::uint32_t sync_cob_ = 0x80;
  std::uint32_t pdo_cob_ = 0x182;
  double u_held_ = pd::kCommandMin;
  std::atomic<std::uint64_t> syncs_{0};
  std::uint64_t dropped_ = 0;
  std::mt19937_64 rng_;
  std::array<std::int32_t, 256> late_{};
  Injection inj_;
  canopen::TimeUs now_us_ = 0;
  bool rebooting_ = false;
  canopen::TimeUs reboot_until_ = 0;
  struct Delayed {
    canopen::Frame frame;
    canopen::TimeUs due;
  };
  std::array<Delayed, 64> delayed_{};  // FIFO (one delay for all)
  std::size_t delayed_head_ = 0, delayed_count_ = 0;
  const canopen::Entry* master_hb_ = nullptr;  // 0x1016:01: whose heartbeat the valve consumes
  std::uint8_t masterId() const;
  void scalingFromDevices();
  canopen::Ref<std::uint8_t> error_mode_{nullptr};
  canopen::Ref<std::int32_t> error_value_{nullptr};
  bool valve_error_ = false;
  std::uint16_t valve_error_code_ = 0;  // the EMCY sent on entering the error state
  canopen::TimeUs valve_changed_us_ = 0;
};

}  // namespace pamc::nodes
