// PDO (CiA 301, 7.2.2): RPDOs (0x1400/0x1600) and TPDOs (0x1800/0x1A00) whose mapping is read from the
// object dictionary and compiled into a copy table; no lookup or allocation per frame.
#pragma once

#include <array>
#include <cstdint>
#include <functional>

#include "canopen/service.hpp"

namespace pamc::canopen {

inline constexpr std::uint32_t kPdoInvalidBit = 0x80000000;   // COB-ID bit 31: PDO does not exist
inline constexpr std::uint32_t kPdoNoRtrBit = 0x40000000;     // COB-ID bit 30: no RTR allowed
inline constexpr std::uint32_t kPdoExtendedBit = 0x20000000;  // COB-ID bit 29: 29-bit identifier (unsupported)
inline constexpr std::uint8_t kPdoSyncAcyclic = 0;            // transmission type 0
inline constexpr std::uint8_t kPdoSyncMax = 240;              // types 1..240: every n-th SYNC
inline constexpr std::uint8_t kPdoEventManufacturer = 254;
inline constexpr std::uint8_t kPdoEventProfile = 255;
inline constexpr std::uint16_t kRpdoCommBase = 0x1400;  // + n - 1: RPDO n's communication parameters
inline constexpr std::uint16_t kRpdoMapBase = 0x1600;
inline constexpr std::uint16_t kTpdoCommBase = 0x1800;  // + n - 1: TPDO n's communication parameters
inline constexpr std::uint16_t kTpdoMapBase = 0x1A00;
inline constexpr unsigned kMaxPdos = 512;
// The COB-ID entry of a TPDO (0x1800-0x19FF sub-index 1).
constexpr bool isTpdoCobId(std::uint16_t index, std::uint8_t sub) {
  return sub == 1 && index >= kTpdoCommBase && index < kTpdoCommBase + kMaxPdos;
}
// The COB-ID entry of any PDO (0x1400-0x15FF or 0x1800-0x19FF sub-index 1).
constexpr bool isPdoCobId(std::uint16_t index, std::uint8_t sub) {
  return isTpdoCobId(index, sub) || (sub == 1 && index >= kRpdoCommBase && index < kRpdoCommBase + kMaxPdos);
}

// A PDO's parameters as the dictionary stores them, read but not judged: the node's own PDOs (PdoMap,
// Rpdo, Tpdo) and tools reading other nodes' EDS files (the candump decoder) parse them here alike.

// One entry of a mapping object (0x1600/0x1A00 + n, sub-index 1..8).
struct PdoMappingEntry {
  std::uint32_t value = 0;  // index << 16 | sub-index << 8 | length in bits
  std::uint16_t index() const { return static_cast<std::uint16_t>(value >> 16); }
  std::uint8_t sub() const { return static_cast<std::uint8_t>(value >> 8); }
  std::uint8_t bits() const { return static_cast<std::uint8_t>(value); }
  bool dummy() const { return index() >= 0x0002 && index() <= 0x0007; }  // a basic data type: bytes skipped
};

struct PdoMapping {
  std::uint64_t count = 0;                   // sub-index 0, as stored
  std::uint8_t read = 0;                     // entries read: count, or those before the first missing one
  std::array<PdoMappingEntry, 8> entries{};  // sub-indices 1..read
};

// Reads mapping object map_index. Returns kSdoOk, kAbortNoObject (no sub-index 0), kAbortValueRange
// (a count above 8) or kAbortNoSubIndex (sub-index read + 1 is missing; the entries before it are
// read, so that a caller checking them in order reports the first problem first).
std::uint32_t readPdoMapping(const ObjectDictionary& od, std::uint16_t map_index, PdoMapping& out);
// The COB-ID of communication object comm_index (sub-index 1); kPdoInvalidBit if it has none.
std::uint32_t readPdoCobId(const ObjectDictionary& od, std::uint16_t comm_index);

// Copy table between a PDO payload and OD storage, compiled from a mapping object.
// Only byte-aligned mappings of numeric entries are supported (and dummy entries 0x0002-0x0007 in RPDOs).
class PdoMap {
 public:
  // Compiles mapping object map_index; returns kSdoOk or an abort code, bad_value gets the offending entry.
  std::uint32_t build(ObjectDictionary& od, std::uint16_t map_index, bool receive, std::uint32_t* bad_value);
  // Checks one mapping value (index << 16 | sub << 8 | bits) without building.
  static std::uint32_t check(const ObjectDictionary& od, std::uint32_t value, bool receive, std::uint8_t* bytes);
  void encode(std::uint8_t* out) const;
  void decode(const std::uint8_t* in) const;
  std::uint8_t size() const { return size_; }
  std::uint8_t count() const { return count_; }
  void clear() { count_ = size_ = 0; }

 private:
  struct Field {
    std::uint8_t* ptr;  // null for a dummy entry
    std::uint8_t len;
  };
  std::array<Field, 8> fields_{};
  std::uint8_t count_ = 0;
  std::uint8_t size_ = 0;
};

// What an RPDO and a TPDO share: where their parameters live (0x14xx/0x16xx or 0x18xx/0x1Axx), the
// communication parameters both read (COB-ID, transmission type, event timer) and the compiled mapping.
class PdoBase {
 public:
  unsigned number() const { return number_; }
  bool valid() const { return valid_; }
  std::uint32_t cobId() const { return cob_id_; }
  std::uint8_t transmissionType() const { return type_; }
  bool synchronous() const { return type_ <= kPdoSyncMax; }
  const PdoMap& map() const { return map_; }

 protected:
  // number is 1-based (RPDO1 uses 0x1400/0x1600).
  PdoBase(NodeContext& ctx, unsigned number, std::uint16_t comm_index, std::uint16_t map_index)
      : ctx_(ctx), number_(number), comm_(comm_index), map_index_(map_index) {}
  ~PdoBase() = default;  // owned as Rpdo or Tpdo, never deleted through the base

  // Reads COB-ID, transmission type and event timer and leaves the PDO invalid; returns the COB-ID
  // entry as stored (bits 31 and 29 tell whether it may be enabled, see enabledBy).
  std::uint32_t readCommParameters();
  // Compiles the mapping (receive: an RPDO's) and checks the transmission type: kSdoOk or why the PDO
  // cannot be enabled.
  std::uint32_t buildMap(bool receive);
  // A COB-ID entry that enables the PDO: bit 31 clear, an 11-bit identifier.
  static bool enabledBy(std::uint32_t cob_entry) { return (cob_entry & (kPdoInvalidBit | kPdoExtendedBit)) == 0; }
  // configure(): throws OdError naming the PDO and its first bad mapping entry unless code is kSdoOk.
  // Only reachable from the EDS: SDO writes are validated before they are stored.
  void throwUnlessOk(std::uint32_t code, bool receive) const;

  NodeContext& ctx_;
  const unsigned number_;
  const std::uint16_t comm_;
  const std::uint16_t map_index_;
  PdoMap map_;
  bool valid_ = false;
  std::uint32_t cob_id_ = 0;
  std::uint8_t type_ = kPdoEventManufacturer;
  TimeUs event_timer_us_ = 0;
};

class Rpdo : public PdoBase {
 public:
  using TimeoutHook = std::function<void(unsigned number, TimeUs now)>;

  // number is 1-based (RPDO1 uses 0x1400/0x1600).
  Rpdo(NodeContext& ctx, unsigned number, std::uint16_t comm_index, std::uint16_t map_index)
      : PdoBase(ctx, number, comm_index, map_index) {}
  void setTimeoutHook(TimeoutHook h) { timeout_hook_ = std::move(h); }
  void registerHooks();
  // Reads the communication and mapping parameters; throws OdError for an invalid mapping.
  void configure() { throwUnlessOk(reconfigure(), true); }
  // Same without throwing (run-time path after an SDO write); returns kSdoOk or why the PDO is off.
  std::uint32_t reconfigure();

  void onFrame(const Frame& f, TimeUs now);
  // SYNC: applies data received since the previous SYNC (synchronous types) and updates freshness.
  void onSync(TimeUs now);
  void advance(TimeUs now);
  TimeUs nextDeadline() const;
  // Drops buffered data (leaving Operational).
  void reset() { rx_ = Reception{}; }

  std::uint64_t received() const { return stats_.received; }
  std::uint64_t wrongLength() const { return stats_.wrong_length; }
  // Synchronous RPDOs: one frame per SYNC cycle is expected. Frames after the synchronous window
  // (0x1007) are discarded (late); a repeat with the same data is ignored (duplicate); a repeat with
  // other data discards the cycle's data (conflict: two producers, or a frame from an earlier cycle).
  std::uint64_t late() const { return stats_.late; }
  std::uint64_t duplicates() const { return stats_.duplicates; }
  std::uint64_t conflicts() const { return stats_.conflicts; }
  // The cycle latched at the last SYNC had a conflict (its data were discarded).
  bool conflictInLastCycle() const { return rx_.conflict_latched; }
  // SYNCs since data last arrived (0: in the cycle before this SYNC); UINT32_MAX before the first.
  // Lets the application count missing PDOs.
  std::uint32_t syncsSinceReception() const { return rx_.syncs_since_rx; }
  bool timedOut() const { return rx_.timed_out; }  // event timer (deadline monitoring) expired
  TimeUs lastReceptionUs() const { return rx_.last_rx_us; }

 private:
  // The reception state reset() drops: data waiting for the next SYNC, the cycle's checks, freshness.
  struct Reception {
    std::uint8_t pending[8] = {};
    bool has_pending = false;
    bool rx_since_sync = false;
    bool timed_out = false;
    TimeUs last_rx_us = kNever;
    bool conflict = false;                      // in the cycle being received
    bool conflict_latched = false;              // in the cycle latched at the last SYNC
    std::uint32_t syncs_since_rx = UINT32_MAX;  // UINT32_MAX: nothing received yet
  };
  // What the RPDO has counted since it was built (reset() keeps it).
  struct Stats {
    std::uint64_t received = 0;
    std::uint64_t wrong_length = 0;
    std::uint64_t late = 0;
    std::uint64_t duplicates = 0;
    std::uint64_t conflicts = 0;
  };
  // Synchronous types: false if f is late, a duplicate or a conflict for this cycle (counted here).
  bool acceptSynchronous(const Frame& f, TimeUs now);

  TimeoutHook timeout_hook_;
  bool subscribed_ = false;
  Reception rx_;
  Stats stats_;
};

class Tpdo : public PdoBase {
 public:
  // change_of_state: event-driven TPDOs also send when their mapped data changed (checked in advance()).
  Tpdo(NodeContext& ctx, unsigned number, std::uint16_t comm_index, std::uint16_t map_index, bool change_of_state)
      : PdoBase(ctx, number, comm_index, map_index), change_of_state_(change_of_state) {}
  void registerHooks();
  void configure() { throwUnlessOk(reconfigure(), false); }
  std::uint32_t reconfigure();

  // SYNC: synchronous types count SYNCs and send (after the application callback has run).
  void onSync(std::uint8_t counter, TimeUs now);
  void advance(TimeUs now);
  TimeUs nextDeadline() const;
  // Application event: event-driven types send as soon as the inhibit time allows, type 0 on the next SYNC.
  void request() { pending_ = true; }
  // Entering Operational: event-driven PDOs send once, synchronous counters restart.
  void start(TimeUs now);

  std::uint64_t sent() const { return sent_; }

 private:
  bool eventDriven() const { return type_ >= kPdoEventManufacturer; }
  bool changed() const;
  void transmit(TimeUs now);
  const bool change_of_state_;
  TimeUs inhibit_us_ = 0;
  std::uint8_t sync_start_ = 0;
  bool waiting_for_start_ = false;
  std::uint8_t sync_count_ = 0;
  bool pending_ = false;
  bool has_sent_ = false;
  TimeUs last_tx_us_ = 0;
  std::uint8_t last_[8] = {};
  std::uint64_t sent_ = 0;
};

}  // namespace pamc::canopen
