// The plant emulator on the bus: the sensor node (od/sensor.eds, CiA 406; nodes/emulated_sensor.hpp)
// and the valve node (od/valve.eds, CiA 401; nodes/emulated_valve.hpp) of the rig, played by one
// process around the emulator physics, with the faults it injects (EmulatorConfig, Injection). With
// several channels: a sensor node and a plant per muscle, one valve module with an output per muscle.
// Stepped by the SYNCs it receives: on SYNC k the muscle is advanced over (k-1, k] under the valve
// command latched at SYNC k-1, the position is put into 0x6004 (sent in the sensor's TPDO after this
// SYNC) and the pressure into 0x6401:01; then the valve latches the command received during the last
// cycle, which holds over (k, k+1].
#pragma once

#include <atomic>
#include <memory>
#include <vector>

#include "canopen/node.hpp"
#include "nodes/emulated_sensor.hpp"
#include "nodes/emulated_valve.hpp"
#include "nodes/emulator_config.hpp"
#include "nodes/process_data.hpp"
#include "plant/plant.hpp"

namespace pamc::nodes {

class EmulatorNodes : public canopen::BusClient {
 public:
  EmulatorNodes(const EmulatorConfig& cfg, canopen::Transport& transport);
  void start(canopen::TimeUs now);

  void onFrame(const canopen::Frame& f, canopen::TimeUs now) override;
  void advance(canopen::TimeUs now) override;
  canopen::TimeUs nextDeadline() const override;

  std::size_t channels() const { return plant_of_.size(); }
  std::size_t sensors() const { return sensors_.size(); }
  canopen::Node& sensor(std::size_t s = 0) { return sensors_[s]->node(); }
  canopen::Node& valve(std::size_t module = 0) { return valves_[module]->node(); }
  std::size_t valveModules() const { return valves_.size(); }
  const plant::Plant& plant(std::size_t c = 0) const { return *plant_of_[c]; }
  const plant::AntagonisticJoint& joint(std::size_t j) const { return *joints_[j]; }
  // Safe from another thread.
  double time() const { return static_cast<double>(syncs_.load(std::memory_order_relaxed)) * cfg_.plant.Ts; }
  std::uint64_t pdosDropped() const { return faulty().pdosDropped(); }

  Injection& inject() { return inj_; }
  // The sensor goes off (silent and deaf) for downtime, then comes back through an NMT reset: boot-up
  // and Pre-operational, as after a power cycle.
  void rebootSensor(canopen::TimeUs downtime_us) { sensors_[sensor_of_[cfg_.fault_channel]]->reboot(downtime_us); }
  // What the valve outputs (0..10 V), whether it is at its error value, and when the output last changed.
  double valveVolts(std::size_t c = 0) const { return valves_[module_[c]]->volts(output_[c]); }
  bool valveInError(std::size_t c = 0) const { return valves_[module_[c]]->inError(); }
  canopen::TimeUs valveChangedUs(std::size_t c = 0) const { return valves_[module_[c]]->changedUs(output_[c]); }

 private:
  void addValves(canopen::Transport& transport);
  void scalingFromDevices();
  void onSync();
  const EmulatedSensor& faulty() const { return *sensors_[sensor_of_[cfg_.fault_channel]]; }
  void addPlants();
  void addSensors(canopen::Transport& transport);
  std::int32_t counts(std::size_t sensor, bool measured = true) noexcept;  // what the sensor measures now

  EmulatorConfig cfg_;    // before the devices, which keep references to it and to inj_
  EmulatorConfig clean_;  // the sensors without faults see this one ...
  Injection inj_;
  Injection none_;                                        // ... and this
  std::vector<std::unique_ptr<EmulatedSensor>> sensors_;  // one per sensor node (a joint's two channels share one)
  std::vector<std::size_t> sensor_of_;                    // each channel's
  std::vector<int> sensor_joint_;                         // each sensor's joint (-1: a muscle's own)
  std::vector<std::size_t> sensor_channel_;               // ... else its channel
  std::vector<std::unique_ptr<EmulatedValve>> valves_;    // the modules
  std::vector<std::size_t> module_, output_;              // each channel's module and output
  std::vector<std::unique_ptr<plant::Plant>> plants_;     // the muscles in no joint
  std::vector<std::unique_ptr<plant::AntagonisticJoint>> joints_;  // the pairs
  std::vector<plant::Plant*> plant_of_;                            // each channel's
  std::vector<int> joint_of_;                                      // each channel's joint (-1: none)
  std::uint32_t sync_cob_ = 0x80;
  std::atomic<std::uint64_t> syncs_{0};
};

}  // namespace pamc::nodes
