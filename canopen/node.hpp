// A CANopen node: the CiA 301 services composed over one object dictionary. Passive core: frames in via
// onFrame(frame, now), frames out via the Transport, time moves only in advance(now).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "canopen/bus.hpp"
#include "canopen/dispatcher.hpp"
#include "canopen/eds.hpp"
#include "canopen/emcy.hpp"
#include "canopen/heartbeat.hpp"
#include "canopen/nmt.hpp"
#include "canopen/od.hpp"
#include "canopen/pdo.hpp"
#include "canopen/sdo_client.hpp"
#include "canopen/sdo_server.hpp"
#include "canopen/service.hpp"
#include "canopen/sync.hpp"

namespace pamc::canopen {

struct NodeOptions {
  TimeUs sdo_timeout_us = 1'000'000;
  std::size_t sdo_client_buffer = 1024;
  // Event-driven TPDOs (254/255) also send when their mapped data changed.
  bool tpdo_change_of_state = true;
  // Go Operational right after boot-up, for nodes that run without an NMT master.
  bool auto_operational = false;
};

class Node : public BusClient {
 public:
  using SyncCallback = std::function<void(std::uint8_t counter, TimeUs now)>;
  using StateCallback = std::function<void(NmtState from, NmtState to, TimeUs now)>;
  using ResetCallback = std::function<void(NmtCommand cmd, TimeUs now)>;
  using ErrorFrameCallback = std::function<void(const Frame& frame, TimeUs now)>;
  // A frame arrived on a COB-ID this node transmits itself (heartbeat/boot-up, EMCY, SDO response,
  // TPDO, SYNC when producing): another node uses this node's ID or identifiers. Not dispatched.
  using CollisionCallback = std::function<void(const Frame& frame, TimeUs now)>;
  using TimerCallback = std::function<void(TimeUs now)>;

  // Configures every service from od; throws OdError for an inconsistent dictionary (e.g. a bad PDO mapping).
  Node(ObjectDictionary od, std::uint8_t node_id, Transport& transport, NodeOptions options = {});
  // Loads an EDS; node_id 0 takes [DeviceComissioning] NodeID. Throws EdsError/OdError.
  static std::unique_ptr<Node> fromEds(const std::string& eds_path, Transport& transport, std::uint8_t node_id = 0,
                                       NodeOptions options = {});
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;

  // Initialising -> boot-up frame -> Pre-operational (-> Operational with auto_operational).
  void start(TimeUs now);

  // BusClient: the only entry points that move the node.
  void onFrame(const Frame& frame, TimeUs now) override;
  void advance(TimeUs now) override;
  TimeUs nextDeadline() const override;

  // Application hook run on every SYNC. Cycle order (CiA 301 synchronous window):
  //   SYNC -> latch synchronous RPDOs into the OD -> onSync(counter, now) -> send synchronous TPDOs.
  // It runs in Pre-operational and Operational; PDOs only move in Operational.
  void onSync(SyncCallback cb) { app_.sync = std::move(cb); }
  void onStateChange(StateCallback cb) { app_.state = std::move(cb); }
  // After reset node / reset communication restored the defaults, before the boot-up frame.
  void onReset(ResetCallback cb) { app_.reset = std::move(cb); }
  void onHeartbeat(HeartbeatConsumer::EventHook cb) { heartbeat_consumer_.setHook(std::move(cb)); }
  void onEmcy(Emcy::ConsumerHook cb) { emcy_.setConsumerHook(std::move(cb)); }
  void onRpdoTimeout(Rpdo::TimeoutHook cb);
  void onErrorFrame(ErrorFrameCallback cb) { app_.error_frame = std::move(cb); }
  void onCollision(CollisionCallback cb) { app_.collision = std::move(cb); }
  // SYNC consumer: no SYNC within 1.5 periods of 0x1006 (see Sync).
  void onSyncTimeout(Sync::TimeoutHook cb) { sync_.setTimeoutHook(std::move(cb)); }
  // One application timer (an NMT master's boot timeouts): cb runs from advance() once the time set with
  // setTimer() has come, then the timer is off until set again; kNever turns it off.
  void onTimer(TimerCallback cb) { app_.timer = std::move(cb); }
  void setTimer(TimeUs at) { timer_at_ = at; }
  // True if this node itself transmits on cob_id (what the collision check uses).
  bool transmitsOn(std::uint32_t cob_id) const;

  std::uint8_t nodeId() const { return ctx_.node_id; }
  NmtState nmtState() const { return ctx_.state; }
  TimeUs now() const { return ctx_.now; }
  ObjectDictionary& od() { return od_; }
  const Counters& counters() const { return counters_; }
  // Frames the transport holds that have not gone out yet (0 on an ideal bus).
  std::size_t txBacklog() const { return ctx_.transport.queued(); }
  // Frames the transport dropped at their deadline (SYNC, synchronous TPDOs that could not go out in time).
  std::uint64_t txExpired() const { return ctx_.transport.expiredCount(); }

  // NMT: apply a command to this node / send one as master (does not change this node's state).
  void applyNmt(NmtCommand cmd) { nmt_.apply(cmd, ctx_.now); }
  bool sendNmt(NmtCommand cmd, std::uint8_t target_node) { return nmt_.sendCommand(cmd, target_node); }

  Nmt& nmt() { return nmt_; }
  Sync& sync() { return sync_; }
  HeartbeatProducer& heartbeatProducer() { return heartbeat_producer_; }
  HeartbeatConsumer& heartbeatConsumer() { return heartbeat_consumer_; }
  Emcy& emcy() { return emcy_; }
  SdoServer& sdoServer() { return sdo_server_; }
  SdoClient& sdoClient() { return sdo_client_; }
  // PDOs by number as in the OD (RPDO1 = 0x1400/0x1600); throw OdError if absent (configuration time).
  Rpdo& rpdo(unsigned number);
  Tpdo& tpdo(unsigned number);
  const std::vector<std::unique_ptr<Rpdo>>& rpdos() const { return rpdos_; }
  const std::vector<std::unique_ptr<Tpdo>>& tpdos() const { return tpdos_; }

 private:
  void handleSync(std::uint8_t counter, TimeUs now);
  void handleStateChange(NmtState from, NmtState to, TimeUs now);
  void handleReset(NmtCommand cmd, TimeUs now);
  // Re-reads every communication parameter (after a reset); never throws.
  void reconfigure(TimeUs now);

  ObjectDictionary od_;
  Counters counters_;
  Dispatcher dispatcher_;
  NodeContext ctx_;
  NodeOptions options_;
  Nmt nmt_;
  HeartbeatProducer heartbeat_producer_;
  HeartbeatConsumer heartbeat_consumer_;
  Sync sync_;
  Emcy emcy_;
  SdoServer sdo_server_;
  SdoClient sdo_client_;
  std::vector<std::unique_ptr<Rpdo>> rpdos_;
  std::vector<std::unique_ptr<Tpdo>> tpdos_;
  // The enabled ones, which the cycle walks (an EDS may have spare PDOs for more channels): rebuilt
  // when a PDO was reconfigured, within the capacity reserved at construction (nothing allocated).
  void refreshLive() noexcept;
  std::vector<Rpdo*> live_rpdos_;
  std::vector<Tpdo*> live_tpdos_;
  std::uint32_t live_epoch_ = ~0u;
  // What the application registered (onSync, onStateChange, ...); each may be empty.
  struct AppCallbacks {
    SyncCallback sync;
    StateCallback state;
    ResetCallback reset;
    ErrorFrameCallback error_frame;
    CollisionCallback collision;
    TimerCallback timer;
  };
  AppCallbacks app_;
  TimeUs timer_at_ = kNever;
};

}  // namespace pamc::canopen
