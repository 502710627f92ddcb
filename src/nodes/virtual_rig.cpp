#include "nodes/virtual_rig.hpp"

#include <memory>
#include <stdexcept>

#include "canopen/candump_log.hpp"

namespace pamc::nodes {

VirtualRigResult runVirtualRig(const ControllerNodeConfig& c, const EmulatorConfig& e, double duration_s,
                               const std::string& candump_log, canopen::TimeUs epoch_us, std::uint32_t bitrate) {
  canopen::VirtualBus bus;
  if (bitrate > 0) bus.setBitrate(bitrate);
  auto& cport = bus.addPort();
  auto& eport = bus.addPort();
  auto ctrlp = std::make_unique<ControllerNode>(c, cport, [&bus] { return bus.now(); });  // rings: heap
  auto& ctrl = *ctrlp;
  auto emup = std::make_unique<EmulatorNodes>(e, eport);
  auto& emu = *emup;
  cport.setClient(&ctrl.node());
  eport.setClient(&emu);
  std::unique_ptr<canopen::CandumpWriter> log;
  if (!candump_log.empty()) {
    log = std::make_unique<canopen::CandumpWriter>(candump_log, "vcan0");
    bus.addTap(log->tap(epoch_us));
  }
  emu.start(bus.now());
  ctrl.start(bus.now());
  VirtualRigResult r;
  const double limit_s = duration_s + c.preroll_s + 30.0;  // give up if it never starts
  CycleRecord rec;
  while (ctrl.runTime() < duration_s) {
    bus.advanceBy(1000);
    while (ctrl.records().pop(rec)) r.records.push_back(rec);
    if (bus.now() * 1e-6 > limit_s) break;
  }
  while (ctrl.records().pop(rec)) r.records.push_back(rec);
  if (log) log->flush();
  r.stats = ctrl.stats();
  r.frames = bus.framesDelivered();
  r.faults = ctrl.faultsRaised();
  r.final_fault = ctrl.fault();
  r.counters = ctrl.node().counters();
  r.bus_busy_us = bus.busyUs();
  return r;
}

}  // namespace pamc::nodes
