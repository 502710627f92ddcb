#pragma once
// NMT master of a set of slaves (CiA 301 7.2.8, the start-up of CiA 302-2, in the order Lely's master
// has it). At the master's start the slaves it is to boot (0x1F81 bit 2) are reset communication: all
// at once (000#8200) when no slave is kept alive (0x1F81 bit 4), otherwise each not kept alive by
// itself. Then every boot slave goes through the "boot slave" process:
//   1. (after a reset) its boot-up awaited (kBootUpTimeoutUs);
//   2. identity: 0x1000 read always (it also proves the slave is there), compared only where 0x1F84
//      expects a device type, then 0x1018:01..04 against 0x1F85-0x1F88 (0: not read);
//   3. the application's reads (addReads(): values a driver needs before the slave starts);
//   4. kept alive only: its heartbeat tells whether it runs - Operational, it is left as it is (no
//      configuration) and goes on at 7; otherwise it is reset communication, and after its boot-up
//      goes on at 5 (its identity is not read again);
//   5. configuration: the concise DCF 0x1F22 (CiA 302-3) written, then every entry read back; a PDO
//      COB-ID (0x1400/0x1800+n:01) is read before its first write and keeps the device's bit 30;
//   6. the application's configuration (addConfig(): a driver's own writes, its values taken when they
//      go out);
//   7. its first heartbeat awaited, if 0x1016 supervises it (within its consumer time);
//   8. NMT start - also to a slave that already runs - once it is not held and every mandatory slave
//      (bit 3) is configured: none with 0x1F80 bit 3; with bit 1 one start for all (000#0100) when
//      every slave may run once the mandatory ones are booted, else each by itself.
// A step the slave does not answer (SDO timeout, no boot-up, no heartbeat) is tried again up to its
// retry factor (0x1F81 bits 8-15); a boot that fails names the step, the entry and the SDO abort code
// (bootError()), and the slave is sent NMT stop. Every mandatory slave must be booted within the boot
// time 0x1F89 (0: no limit). A slave that boots up again later goes through steps 2-8; one that comes
// back after a heartbeat loss is reset communication first (unless kept alive and Operational); one that
// stays in Pre-operational longer than its start grace after a start gets another start. Slaves without
// bit 2 are neither reset nor booted, only started. The application may hold a slave in
// Pre-operational for reasons of its own (a bit per reason); it is started when the last reason is
// released.
//
// Everything comes from the master's own dictionary, read at begin(): 0x1F80 NMT start-up (bit 0
// master, bit 1 start the slaves with one broadcast, bit 2 do not enter Operational by itself - read by
// the application, bit 3 do not start the slaves), 0x1F81, 0x1F84-0x1F88, 0x1F22, 0x1F89, 0x1016.
//
// The master takes the node's heartbeat hook and its application timer, and passes what the application
// must react to on as SlaveEvents. All of it runs on the node's thread, none of it in the SYNC callback
// but poll(), which only lets boot steps that waited for the node's SDO client go on. begin() builds
// the boot plans from the dictionary; after it nothing is allocated except by the SDO transfers of a
// boot and the text of a failure.
#include <array>
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
  Configured,  // the boot finished: identity checked, configuration written and read back, the application's written
  KeptAlive,   // kept alive and Operational at the master's start: identity checked, left as it is (not configured)
  BootFailed,  // the boot failed (bootError()); the slave is sent NMT stop
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
  // The application's configuration (a driver's own writes, Lely's Driver::OnConfig): after the concise
  // DCF and its read-back, before the first heartbeat and the start. value() is taken as it goes out.
  struct Write {
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    std::uint8_t size = 4;  // bytes, 1..4, little-endian
    std::function<std::uint32_t()> value;
  };
  std::vector<Write> config;
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

// The steps of a slave's boot, as a failure names them.
enum class BootStep : std::uint8_t { Reset, Identity, Read, Configuration, ReadBack, Application, Heartbeat, BootTime };
const char* bootStepName(BootStep s);  // "reset communication", "identity check", ..., "application configuration"

struct BootError {
  BootStep step = BootStep::Identity;
  std::uint32_t abort_code = 0;  // SDO abort code (0: none - a mismatch or the master's own timeout, see text)
  std::string text;              // "0x1000:00 device type is 0x00020192, expected 0x00080196", ...
};

class NmtMaster {
 public:
  using EventHook = std::function<void(std::uint8_t id, SlaveEvent event, TimeUs now)>;
  // After NMT reset communication the slave's boot-up must come within this (as Lely's master waits).
  static constexpr TimeUs kBootUpTimeoutUs = 1'000'000;
  // A started slave must report Operational within its start grace: kStartGracePeriods of its heartbeat
  // period (the 0x1017 its configuration writes, else its consumer time 0x1016), at least the floor.
  static constexpr TimeUs kStartGraceFloorUs = 200'000;
  static constexpr unsigned kStartGracePeriods = 3;

  struct Counters {
    std::uint64_t starts = 0;   // NMT start sent to a slave
    std::uint64_t resets = 0;   // slaves reset communication to begin their boot (one broadcast resets several)
    std::uint64_t reboots = 0;  // NMT reset communication to a slave back after a heartbeat loss
    std::uint64_t holds = 0;    // slave sent to Pre-operational by hold()
    std::uint64_t boots = 0;    // boots finished (configured)
    std::uint64_t boot_failures = 0;
    std::uint64_t boot_retries = 0;  // boot steps tried again: SDO timeout, no boot-up, no first heartbeat
    std::uint64_t kept_alive = 0;    // Operational keep-alive slaves left as they were (no reset, no configuration)
  };

  explicit NmtMaster(Node& node);
  NmtMaster(const NmtMaster&) = delete;
  NmtMaster& operator=(const NmtMaster&) = delete;

  // Supervise this node-ID (its heartbeat must be consumed: 0x1016 of the master's dictionary).
  void addSlave(std::uint8_t id);
  // What to check and write at its boot, into the master's dictionary (bootToDictionary), its reads and
  // the application's writes kept (throws for an unknown slave or a dictionary without the master's objects).
  void setBoot(std::uint8_t id, SlaveBoot boot);
  // Adds to the application's reads at the slave's boot, after its identity, before its configuration.
  void addReads(std::uint8_t id, std::vector<SlaveBoot::Read> reads);
  // Adds to the application's writes at the slave's boot, after the concise DCF and its read-back (one per
  // driver: several channels on one slave each add theirs).
  void addConfig(std::uint8_t id, std::vector<SlaveBoot::Write> writes);
  void setStartup(std::uint32_t bits) { startup_ = bits; }
  std::uint32_t startup() const noexcept { return startup_; }
  void onEvent(EventHook hook) { hook_ = std::move(hook); }

  // The master's own start (it entered Operational): 0x1F80 and every slave's boot from the dictionary
  // (bootFromDictionary), then every slave is booted or started.
  void begin(TimeUs now);
  // The master's own stop (it left Operational or was reset): until the next begin() it boots and
  // starts nothing; it still reports what it hears. Boots under way stop where they are.
  void end() noexcept;
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
  // A start went out less than its start grace ago and no Operational heartbeat followed yet.
  bool starting(std::uint8_t id, TimeUs now) const noexcept;
  TimeUs startGraceUs(std::uint8_t id) const noexcept;
  bool timedOut(std::uint8_t id) const { return node_.heartbeatConsumer().timedOut(id); }
  // Boot state: configured (or nothing to configure), in progress, failed.
  bool configured(std::uint8_t id) const noexcept;
  bool booting(std::uint8_t id) const noexcept;
  // The master boots it (0x1F81 bit 2, as read at begin()).
  bool boots(std::uint8_t id) const noexcept;
  const BootError* bootError(std::uint8_t id) const noexcept;  // nullptr unless the last boot failed

  const Counters& counters() const noexcept { return counters_; }

 private:
  // Where a slave's boot stands.
  enum class Boot : std::uint8_t {
    Idle,       // nothing under way (not begun, or not a boot slave)
    Checking,   // kept alive, identity checked: waiting for a heartbeat to tell whether it runs
    Resetting,  // NMT reset communication sent: waiting for its boot-up
    Waiting,    // the next SDO step waits for the node's SDO client
    Running,    // an SDO step is under way
    Heartbeat,  // configured: waiting for its first heartbeat
    Done,
    Failed
  };
  enum class OpKind : std::uint8_t {
    Present,  // 0x1000 read, any value: the slave is there
    Expect,   // an identity entry read and compared
    Read,     // the application's read
    KeepRtr,  // a PDO COB-ID read: its bit 30 into the writes of the entry
    Write,
    Verify,
    Config  // the application's write
  };
  struct Op {
    OpKind kind;
    std::uint16_t index;
    std::uint8_t sub;
    std::uint32_t expected;  // Expect
    std::size_t item;        // Read: reads[item]; KeepRtr / Write / Verify: writes[item]; Config: config[item]
  };
  // A slave's NMT start: owed, sent, held back.
  struct Start {
    TimeUs sent = kNever;                  // NMT start sent, no Operational heartbeat yet
    bool due = false;                      // booted (or not to be booted), hold released: an NMT start is owed
    TimeUs grace_us = kStartGraceFloorUs;  // for a start to show Operational
    std::uint8_t hold = 0;                 // reasons to keep it in Pre-operational
  };
  struct Slave {
    std::uint8_t id = 0;
    bool lost = false;  // heartbeat timed out: re-boot it when it is back
    Start start;
    SlaveBoot boot;                        // from the dictionary at begin(), with reads
    std::vector<SlaveBoot::Read> reads;    // the application's (addReads)
    std::vector<SlaveBoot::Write> config;  // the application's (addConfig)
    std::vector<Op> ops;        // the boot, flattened: identity, reads, writes, read-backs, the application's writes
    std::size_t config_op = 0;  // the first write (a kept-alive slave's state is checked before it)
    std::string plan_error;     // 0x1F22:id did not decode: the boot fails with this
    Boot state = Boot::Idle;
    bool checking = false;    // kept alive: the ops up to config_op, then its state decides (step 4)
    bool identified = false;  // reset by the keep-alive check: its boot-up goes on at the configuration
    bool kept = false;        // kept alive and Operational: left as it is
    std::size_t next_op = 0, end_op = 0;
    unsigned tries_left = 0;   // of the present step
    TimeUs deadline = kNever;  // Checking, Resetting, Heartbeat
    BootError error;
  };
  Slave* find(std::uint8_t id) noexcept;
  const Slave* find(std::uint8_t id) const noexcept;
  void loadPlan(Slave& s);          // boot, ops and start grace from the dictionary (allocates)
  static void configOps(Slave& s);  // the writes, each TPDO COB-ID read first, then the read-backs
  static bool bootable(const Slave& s) noexcept { return (s.boot.assignment & kAssignBoot) != 0; }
  bool mayStartAny() const noexcept;  // begun as master, 0x1F80 bit 3 clear, the mandatory slaves booted
  bool mayStart(const Slave& s) const noexcept;
  bool mandatoryReady() const noexcept;
  bool running(const Slave& s) const noexcept;  // its heartbeat shows it Operational, not timed out
  void startSlave(Slave& s, TimeUs now) noexcept;
  void startReady(TimeUs now) noexcept;

  // The boot process (nmt_boot.cpp), one step after the other.
  bool resetAllAtOnce() const noexcept;  // at the master's start: no slave kept alive, none mid-transfer
  void beginBoot(Slave& s, TimeUs now,
                 bool reset_sent) noexcept;                     // at the master's start: identity (kept alive) or reset
  void reset(Slave& s, TimeUs now, bool send = true) noexcept;  // NMT reset communication, then wait for the boot-up
  void steps(Slave& s, std::size_t from, bool checking) noexcept;  // the SDO steps from ops[from]
  void checkNode(Slave& s, TimeUs now) noexcept;                   // kept alive, identity checked: does it run?
  void keptRunning(Slave& s, TimeUs now) noexcept;
  void resetAfterCheck(Slave& s, TimeUs now) noexcept;
  void runBoot(Slave& s) noexcept;  // issues the next SDO step
  void onBootReply(Slave& s, std::uint32_t code, const std::uint8_t* data, std::size_t len) noexcept;
  bool checkReply(Slave& s, const Op& op, const std::uint8_t* data, std::size_t len) noexcept;
  static void keepRtr(Slave& s, const Op& op, std::uint32_t device_cob) noexcept;
  static BootStep stepOf(OpKind k) noexcept;
  void awaitHeartbeat(Slave& s, TimeUs now) noexcept;
  void done(Slave& s, TimeUs now) noexcept;
  void bootFailed(Slave& s, BootStep step, std::uint32_t code, std::string text) noexcept;
  void onTimer(TimeUs now) noexcept;  // the deadlines of the steps and the boot time
  void arm() noexcept;
  void onBootEvent(Slave& s, HeartbeatEvent ev, NmtState st, TimeUs now) noexcept;

  void onHeartbeat(std::uint8_t id, HeartbeatEvent ev, NmtState st, TimeUs now) noexcept;
  void emit(std::uint8_t id, SlaveEvent e, TimeUs now) {
    if (hook_) hook_(id, e, now);
  }

  Node& node_;
  std::vector<Slave> slaves_;
  std::array<std::uint8_t, 128> slave_of_{};  // node-ID -> its place in slaves_ + 1 (0: not a slave)
  EventHook hook_;
  Counters counters_;
  std::uint32_t startup_ = kStartupMaster;
  bool begun_ = false;
  bool network_started_ = false;   // 0x1F80 bit 1: the start for all decided (sent, or each by itself)
  TimeUs boot_deadline_ = kNever;  // 0x1F89 after begin()
  std::uint32_t boot_time_ms_ = 0;
};

}  // namespace pamc::canopen
