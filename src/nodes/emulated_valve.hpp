// The emulator's valve device (od/valve.eds, CiA 401; od/profile/analog401.eds for a module of four):
// latches the controller's commands at each SYNC and reports the muscles' pressures in 0x6401:n - one
// output and one input per channel. Silent at run time when injected (it still receives).
// It behaves as a CiA 401 output on a communication error: when it is not Operational, its SYNC stops
// (SYNC timeout from its 0x1006, set to the emulator's period) or the controller's heartbeat times out
// (its 0x1016), it outputs its error value 0x6444:01 (0x6443:01 = 1) until it is back in order and
// has latched a fresh command.
#pragma once

#include <array>
#include <cstdint>
#include <memory>

#include "canopen/node.hpp"
#include "nodes/emulator_config.hpp"

namespace pamc::nodes {

// The node is the valve's own transport (send), so an injected silence swallows what it sends.
class EmulatedValve : private canopen::Transport {
 public:
  // id: its node-ID (0: the EDS's); outputs: the channels it drives (command_sub, command_sub + 1, ...).
  EmulatedValve(const EmulatorConfig& cfg, canopen::Transport& bus, const Injection& inj, std::uint8_t id,
                std::size_t outputs);

  canopen::Node& node() { return *node_; }
  const canopen::Node& node() const { return *node_; }
  std::size_t outputs() const { return n_; }
  void reportPressure(double bar, std::size_t c = 0);
  // Applies the command or, on a communication error, the error value; notes when the output changes.
  // At every SYNC, after the node latched the command of the last cycle.
  void update(canopen::TimeUs now);

  // The command it holds (as the plant takes it), what it outputs (0..10 V), whether it is at its
  // error value, and when the output last changed.
  double held(std::size_t c = 0) const { return out_[c].u_held; }
  double volts(std::size_t c = 0) const { return pd::valveVolts(out_[c].u_held); }
  bool inError() const { return error_; }
  canopen::TimeUs changedUs(std::size_t c = 0) const { return out_[c].changed_us; }

 private:
  bool send(const canopen::Frame& f) override;
  std::uint8_t masterId() const;
  void monitorSync();
  void enterError(std::uint16_t cause);
  void leaveError();

  const EmulatorConfig& cfg_;
  canopen::Transport& bus_;
  const Injection& inj_;
  std::unique_ptr<canopen::Node> node_;
  // One analog output with its pressure input.
  struct Output {
    canopen::Ref<std::int16_t> pressure{nullptr};
    canopen::Ref<std::int16_t> command{nullptr};
    canopen::Ref<std::uint8_t> error_mode{nullptr};
    canopen::Ref<std::int32_t> error_value{nullptr};
    double u_held = pd::kCommandMin;
    canopen::TimeUs changed_us = 0;
  };
  void apply(Output& o, canopen::TimeUs now);
  std::array<Output, 8> out_{};
  std::size_t n_ = 1;
  const canopen::Entry* master_hb_ = nullptr;  // 0x1016:01: whose heartbeat the valve consumes
  bool error_ = false;
  std::uint16_t error_code_ = 0;  // the EMCY sent on entering the error state
};

}  // namespace pamc::nodes
