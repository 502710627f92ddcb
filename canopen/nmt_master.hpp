#pragma once
// NMT master of a set of slaves (CiA 301 7.2.8, the start-up of CiA 302-2): a slave is checked and
// configured after its boot-up ("boot slave": its identity 0x1000 / 0x1018 against the expected one, a
// concise DCF written and read back), then started; one that comes back after a heartbeat loss is
// re-booted (reset communication), so it boots up and goes through all of it again - unless it is kept
// alive and reports Operational; one that stays in Pre-operational after a start gets another. A boot
// step the slave does not answer (SDO timeout) is tried again, up to the slave's retry factor. The
// application may hold a slave in Pre-operational for reasons of its own (a bit per reason); it is
// started when the last reason is released.
//
// What a boot does comes from the master's own dictionary, as CiA 302-2 defines it, read at begin():
// 0x1F80 NMT start-up (bit 0 master, bit 1 start the slaves with one broadcast, bit 2 do not enter
// Operational by itself - read by the application, bit 3 do not start the slaves); 0x1F81 slave
// assignment (bit 0 slave, bit 2 boot: check and configure, bit 3 mandatory: no slave is started
// before it is configured, bit 4 keep alive: a slave that is Operational with a live heartbeat is
// neither reset nor configured again - at the master's start and when it comes back after a heartbeat
// loss, bits 8-15 retry factor: how often an unanswered boot step is tried again); 0x1F84-0x1F88 the
// expected device type, vendor-ID, product code, revision and serial number (0: not checked); 0x1F22
// the concise DCF written into the slave (CiA 302-3). The application adds reads of its own
// (setReads(): a driver's values it needs before the slave starts).
//
// The master takes the node's heartbeat hook and passes what the application must react to on as
// SlaveEvents. All of it runs on the node's thread; the boot uses the node's SDO client between
// cycles (poll() retries while the client is busy). begin() builds the boot plans from the
// dictionary; after it nothing is allocated except by the SDO transfers of a boot.
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "canopen/concise_dcf.hpp"
#include "canopen/node.hpp"

namespace pamc::canopen {

enum class SlaveEvent : std::uint8_t {
  Lost,             // its heartbeat timed out
  BootUp,           // it sent a boot-up: it lost its state (the master boots and starts it unless held)
  LeftOperational,  // it reported Pre-operational while not held (the master starts it again)
  Stopped,          // it reported Stopped while not held
  Configured,       // the boot finished: identity checked, configuration written and read back
  BootFailed,       // the boot failed (bootError()); the slave is left in Pre-operational
};
const char* slaveEventName(SlaveEvent e);

// The master's objects (CiA 302-2, CiA 302-3), entries per node-ID.
inline constexpr std::uint16_t kObjConciseDcf = 0x1F22;
inline constexpr std::uint16_t kObjStartup = 0x1F80;
inline constexpr std::uint16_t kObjAssignment = 0x1F81;
inline constexpr std::uint16_t kObjDeviceType = 0x1F84;  // 0x1F85 vendor-ID ... 0x1F88 serial number
inline constexpr std::uint16_t kObjBootTime = 0x1F89;

// 0x1F80 bits.
inline constexpr std::uint32_t kStartupMaster = 0x01;
inline constexpr std::uint32_t kStartupBroadcastStart = 0x02;
inline constexpr std::uint32_t kStartupNoSelfStart = 0x04;
inline constexpr std::uint32_t kStartupNoSlaveStart = 0x08;
inline constexpr std::uint32_t kStartupSupported = 0x0F;
// 0x1F81 bits.
inline constexpr std::uint32_t kAssignSlave = 0x01;
inline constexpr std::uint32_t kAssignBoot = 0x04;
inline constexpr std::uint32_t kAssignMandatory = 0x08;
inline constexpr std::uint32_t kAssignKeepAlive = 0x10;
inline constexpr unsigned kAssignRetryShift = 8;  // bits 8-15: retry factor
constexpr std::uint32_t assignRetries(unsigned n) { return (n & 0xFFu) << kAssignRetryShift; }
constexpr unsigned retriesOf(std::uint32_t assignment) { return (assignment >> kAssignRetryShift) & 0xFFu; }

// What the master checks, reads and writes at a slave's boot: the master's entries for the slave
// (0x1F81, 0x1F84-0x1F88, 0x1F22) and the application's reads.
struct SlaveBoot {
  std::uint32_t assignment = kAssignSlave;  // 0x1F81 bits
  // Expected identity: 0x1000, 0x1018:01..04 (unset or 0: not checked).
  std::optional<std::uint32_t> device_type, vendor_id, product_code, revision, serial;
  // Read before the writes; on_value returns false (with why) to fail the boot.
  struct Read {
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    std::function<bool(const std::uint8_t* data, std::size_t len, std::string* why)> on_value;
  };
  std::vector<Read> reads;
  ConciseDcf writes;  // in order; then the last value of every entry is read back and compared
};

// The slave's boot as the master's dictionary holds it (0x1F81, 0x1F84-0x1F88, 0x1F22; reads stay
// empty); false with why when 0x1F22:id is not a concise DCF.
bool bootFromDictionary(const ObjectDictionary& od, std::uint8_t id, SlaveBoot& out, std::string* why);
// The other way: a plan into the master's entries for the slave. Throws OdError when the dictionary
// lacks one of the objects or the concise DCF does not fit 0x1F22:id.
void bootToDictionary(ObjectDictionary& od, std::uint8_t id, const SlaveBoot& boot);

// A value for one of the master's objects, as a DCF or a tool gives it: "" if the master can take it,
// otherwise the problem (0x1F22: not a concise DCF).
std::string checkMasterEntry(const DcfEntry& e);

struct BootError {
  std::uint32_t abort_code = 0;  // SDO abort code (0: a mismatch, see text)
  std::string text;              // "0x1000 device type is 0x00020192, expected 0x00080196", ...
};

class NmtMaster {
 public:
  using EventHook = std::function<void(std::uint8_t id, SlaveEvent event, TimeUs now)>;
  // A started slave must report Operational within this time (three heartbeats of 100 ms).
  static constexpr TimeUs kStartGraceUs = 300'000;

  struct Counters {
    std::uint64_t starts = 0;   // NMT start sent to a slave
    std::uint64_t reboots = 0;  // NMT reset communication to a slave back after a heartbeat loss
    std::uint64_t holds = 0;    // slave sent to Pre-operational by hold()
    std::uint64_t boots = 0;    // boots finished (configured)
    std::uint64_t boot_failures = 0;
    std::uint64_t boot_retries = 0;  // boot steps tried again after an SDO timeout
    std::uint64_t kept_alive = 0;    // Operational keep-alive slaves left as they were (no reset, no boot)
  };

  explicit NmtMaster(Node& node);
  NmtMaster(const NmtMaster&) = delete;
  NmtMaster& operator=(const NmtMaster&) = delete;

  // Supervise this node-ID (its heartbeat must be consumed: 0x1016 of the master's dictionary).
  void addSlave(std::uint8_t id);
  // What to check and write at its boot, into the master's dictionary (bootToDictionary), its reads
  // kept (throws for an unknown slave or a dictionary without the master's objects).
  void setBoot(std::uint8_t id, SlaveBoot boot);
  // The application's reads at the slave's boot, after its identity, before its configuration.
  void setReads(std::uint8_t id, std::vector<SlaveBoot::Read> reads);
  void setStartup(std::uint32_t bits) { startup_ = bits; }
  std::uint32_t startup() const noexcept { return startup_; }
  void onEvent(EventHook hook) { hook_ = std::move(hook); }

  // The master's own start (it entered Operational): 0x1F80 and every slave's boot from the dictionary
  // (bootFromDictionary), then every slave is booted or started.
  void begin(TimeUs now);
  // The master's own stop (it left Operational or was reset): until the next begin() it boots and
  // starts nothing; it still reports what it hears.
  void end() noexcept { begun_ = false; }
  bool begun() const noexcept { return begun_; }
  // Boot and start work left waiting for the SDO client; call between cycles (cheap when idle).
  void poll(TimeUs now) noexcept;

  // NMT start when the slave may run: not held, booted if it is to be, mandatory slaves ready.
  void start(std::uint8_t id, TimeUs now) noexcept;
  // Keep the slave in Pre-operational for `reason` (a bit); the first reason sends it there.
  void hold(std::uint8_t id, std::uint8_t reason) noexcept;
  // Drop `reason`; with no reason left the slave is started.
  void release(std::uint8_t id, std::uint8_t reason, TimeUs now) noexcept;
  std::uint8_t holdReasons(std::uint8_t id) const noexcept;

  // The slave cannot run: Stopped, or Pre-operational beyond the grace after a start (then another
  // start is sent).
  bool down(std::uint8_t id, TimeUs now) noexcept;
  // A start went out less than kStartGraceUs ago and no Operational heartbeat followed yet.
  bool starting(std::uint8_t id, TimeUs now) const noexcept;
  bool timedOut(std::uint8_t id) const { return node_.heartbeatConsumer().timedOut(id); }
  // Boot state: configured (or nothing to configure), in progress, failed.
  bool configured(std::uint8_t id) const noexcept;
  bool booting(std::uint8_t id) const noexcept;
  const BootError* bootError(std::uint8_t id) const noexcept;  // nullptr unless the last boot failed

  const Counters& counters() const noexcept { return counters_; }

 private:
  enum class Boot : std::uint8_t { Idle, Waiting, Running, Done, Failed };
  enum class OpKind : std::uint8_t { Expect, Read, Write, Verify };
  struct Op {
    OpKind kind;
    std::uint16_t index;
    std::uint8_t sub;
    std::uint32_t expected;  // Expect
    std::size_t item;        // Read: reads[item]; Write / Verify: writes[item]
  };
  struct Slave {
    std::uint8_t id = 0;
    bool lost = false;             // heartbeat timed out: re-boot it when it is back
    TimeUs start_sent = kNever;    // NMT start sent, no Operational heartbeat yet
    std::uint8_t hold = 0;         // reasons to keep it in Pre-operational
    SlaveBoot boot;                // from the dictionary at begin(), with reads
    std::vector<SlaveBoot::Read> reads;  // the application's (setReads)
    std::vector<Op> ops;           // the boot, flattened
    std::string plan_error;        // 0x1F22:id did not decode: the boot fails with this
    Boot state = Boot::Idle;
    std::size_t next_op = 0;
    unsigned retries_left = 0;     // of this boot
    bool resume = false;           // Waiting for the SDO client in the middle of a boot: go on at next_op
    BootError error;
  };
  Slave* find(std::uint8_t id) noexcept;
  const Slave* find(std::uint8_t id) const noexcept;
  void loadPlan(Slave& s);  // boot and ops from the dictionary (allocates)
  static bool bootable(const Slave& s) noexcept;  // 0x1F81 bit 2 and something to check or write
  bool mayStart(const Slave& s) const noexcept;
  bool mandatoryReady() const noexcept;
  // Kept alive (0x1F81 bit 4) and Operational with a live heartbeat: leave it as it is.
  bool keptAlive(const Slave& s) const noexcept;
  void startSlave(Slave& s, TimeUs now) noexcept;
  void startReady(TimeUs now) noexcept;
  void bootSlave(Slave& s, TimeUs now) noexcept;  // begins the boot, or starts it when nothing to check
  void runBoot(Slave& s) noexcept;                // issues the next operation
  void onBootReply(Slave& s, std::uint32_t code, const std::uint8_t* data, std::size_t len) noexcept;
  void bootFailed(Slave& s, std::uint32_t code, std::string text) noexcept;
  void onHeartbeat(std::uint8_t id, HeartbeatEvent ev, NmtState st, TimeUs now) noexcept;
  void emit(std::uint8_t id, SlaveEvent e, TimeUs now) {
    if (hook_) hook_(id, e, now);
  }

  Node& node_;
  std::vector<Slave> slaves_;
  EventHook hook_;
  Counters counters_;
  std::uint32_t startup_ = kStartupMaster;
  bool begun_ = false;
  bool broadcast_sent_ = false;
};

}  // namespace pamc::canopen
