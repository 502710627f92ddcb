// What every CiA 301 service of a node shares: NMT state, run-time counters and the send path.
#pragma once

#include <cstdint>

#include "canopen/bus.hpp"
#include "canopen/dispatcher.hpp"
#include "canopen/frame.hpp"
#include "canopen/od.hpp"

namespace pamc::canopen {

// NMT states; the values are the ones a heartbeat frame carries (CiA 301, 7.2.8.3.2.2).
enum class NmtState : std::uint8_t { Initialising = 0x00, Stopped = 0x04, Operational = 0x05, PreOperational = 0x7F };

const char* nmtStateName(NmtState s);

// Run-time problems are counted, never thrown (the cyclic path must not fail).
struct Counters {
  std::uint64_t rx_frames = 0;
  std::uint64_t tx_frames = 0;
  std::uint64_t tx_dropped = 0;          // the transport refused the frame (queue full)
  std::uint64_t unknown_cob_id = 0;      // no service listens to the identifier
  std::uint64_t wrong_length = 0;        // a service's frame with a DLC the protocol does not allow
  std::uint64_t rpdo_wrong_length = 0;   // ... of them RPDOs (a length other than their mapping's)
  std::uint64_t unsupported_frames = 0;  // RTR or 29-bit frames (CANopen here uses 11-bit data frames)
  std::uint64_t error_frames = 0;        // SocketCAN error frames
  std::uint64_t ignored_in_state = 0;    // valid frames the current NMT state does not process
  std::uint64_t nmt_invalid_command = 0;
  std::uint64_t sync_overruns = 0;  // SYNC producer woke more than one period late and skipped SYNCs
  std::uint64_t sdo_aborts_sent = 0;
  std::uint64_t sdo_aborts_received = 0;
  std::uint64_t emcy_dropped = 0;       // EMCY queue full while the inhibit time ran
  std::uint64_t sync_timeouts = 0;      // SYNC consumer: no SYNC within 1.5 periods of 0x1006
  std::uint64_t rpdo_late = 0;          // synchronous RPDO after the synchronous window (0x1007): discarded
  std::uint64_t rpdo_duplicates = 0;    // synchronous RPDO repeated with the same data in one cycle: ignored
  std::uint64_t rpdo_conflicts = 0;     // synchronous RPDO repeated with other data in one cycle: cycle discarded
  std::uint64_t cob_id_collisions = 0;  // a frame on a COB-ID this node transmits (another node with its ID)
};

struct NodeContext {
  std::uint8_t node_id;
  ObjectDictionary& od;
  Dispatcher& dispatcher;
  Transport& transport;
  Counters& counters;
  NmtState state = NmtState::Initialising;
  TimeUs now = 0;                // the last time the node was told (onFrame/advance); services never read a clock
  TimeUs last_sync_us = kNever;  // last SYNC produced or consumed (kNever: none since configuration)
  TimeUs sync_window_us = 0;     // 0x1007 synchronous window length (0: not used)
  std::uint32_t pdo_epoch = 0;   // counts the PDOs' reconfigurations (the node's list of live ones follows)

  bool send(const Frame& f) {
    if (transport.send(f)) {
      ++counters.tx_frames;
      return true;
    }
    ++counters.tx_dropped;
    return false;
  }
  // A frame that must not go out after deadline (SYNC, synchronous TPDO).
  bool sendUntil(const Frame& f, TimeUs deadline) {
    if (transport.sendUntil(f, deadline)) {
      ++counters.tx_frames;
      return true;
    }
    ++counters.tx_dropped;
    return false;
  }
  // Services are "alive" (SDO, SYNC, EMCY) in Pre-operational and Operational.
  bool communicating() const { return state == NmtState::PreOperational || state == NmtState::Operational; }
  bool operational() const { return state == NmtState::Operational; }
};

}  // namespace pamc::canopen
