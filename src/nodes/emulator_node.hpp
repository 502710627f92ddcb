// The plant emulator on the bus: the sensor node (od/sensor.eds, CiA 406) and the valve node
// (od/valve.eds, CiA 401) of the rig, played by one process around the emulator physics.
// Stepped by the SYNCs it receives: on SYNC k the muscle is advanced over (k-1, k] under the valve
// command latched at SYNC k-1, the position is put into 0x6004 (sent in the sensor's TPDO after this
// SYNC) and the pressure into 0x6401:01; then the valve latches the command received during the last
// cycle, which holds over (k, k+1].
// Fault injection: sensor silent from a time on (for a while), position PDOs dropped at random or
// late by whole cycles, a payload step.
#pragma once

#include <atomic>
#include <memory>
#include <random>
#include <string>

#include "canopen/node.hpp"
#include "plant/plant.hpp"

namespace pamc::nodes {

struct EmulatorConfig {
  std::string sensor_eds = "od/sensor.eds";
  std::string valve_eds = "od/valve.eds";
  plant::PlantConfig plant = plant::PlantConfig::defaults();
  double sensor_silent_at_s = -1;   // < 0: never
  double sensor_silent_for_s = 1e9;
  double drop_pdo_prob = 0.0;       // probability of dropping a position PDO
  int late_pdo_cycles = 0;          // position reported this many cycles late
  double payload_at_s = -1;         // < 0: no payload step
  double payload_N = 40.0;
  std::uint64_t seed = 7;
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

 private:
  // The sensor's frames pass through here, so faults can silence or thin them.
  class FaultyLink : public canopen::Transport {
   public:
    FaultyLink(EmulatorNodes& owner, canopen::Transport& inner) : owner_(owner), inner_(inner) {}
    bool send(const canopen::Frame& f) override;

   private:
    EmulatorNodes& owner_;
    canopen::Transport& inner_;
  };
  bool sensorSilent() const;

  EmulatorConfig cfg_;
  FaultyLink sensor_link_;
  std::unique_ptr<canopen::Node> sensor_, valve_;
  plant::Plant plant_;
  canopen::Ref<std::int32_t> position_{nullptr};
  canopen::Ref<std::int16_t> pressure_{nullptr};
  canopen::Ref<std::int16_t> command_{nullptr};
  std::uint32_t sync_cob_ = 0x80;
  std::uint32_t pdo_cob_ = 0x182;
  double u_held_ = -5.0;
  std::atomic<std::uint64_t> syncs_{0};
  std::uint64_t dropped_ = 0;
  std::mt19937_64 rng_;
  std::array<std::int32_t, 256> late_{};
};

}  // namespace pamc::nodes
