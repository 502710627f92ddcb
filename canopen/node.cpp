#include "canopen/node.hpp"

#include <algorithm>

#include "canopen/eds_dictionary.hpp"

namespace pamc::canopen {

Node::Node(ObjectDictionary od, std::uint8_t node_id, Transport& transport, NodeOptions options)
    : od_(std::move(od)),
      ctx_{node_id, od_, dispatcher_, transport, counters_},
      options_(options),
      nmt_(ctx_),
      heartbeat_producer_(ctx_),
      heartbeat_consumer_(ctx_),
      sync_(ctx_),
      emcy_(ctx_),
      sdo_server_(ctx_, options.sdo_timeout_us),
      sdo_client_(ctx_, options.sdo_timeout_us, options.sdo_client_buffer) {
  if (node_id == 0 || node_id > 127) throw OdError("node-ID must be 1..127, got " + std::to_string(node_id));

  for (unsigned i = 0; i < kMaxPdos; ++i) {
    auto comm = static_cast<std::uint16_t>(kRpdoCommBase + i);
    if (!od_.hasObject(comm)) continue;
    auto map = static_cast<std::uint16_t>(kRpdoMapBase + i);
    if (!od_.hasObject(map)) throw OdError("RPDO" + std::to_string(i + 1) + ": mapping object missing");
    rpdos_.push_back(std::make_unique<Rpdo>(ctx_, i + 1, comm, map));
  }
  for (unsigned i = 0; i < kMaxPdos; ++i) {
    auto comm = static_cast<std::uint16_t>(kTpdoCommBase + i);
    if (!od_.hasObject(comm)) continue;
    auto map = static_cast<std::uint16_t>(kTpdoMapBase + i);
    if (!od_.hasObject(map)) throw OdError("TPDO" + std::to_string(i + 1) + ": mapping object missing");
    tpdos_.push_back(std::make_unique<Tpdo>(ctx_, i + 1, comm, map, options.tpdo_change_of_state));
  }
  live_rpdos_.reserve(rpdos_.size());
  live_tpdos_.reserve(tpdos_.size());

  nmt_.setHooks([this](NmtState from, NmtState to, TimeUs now) { handleStateChange(from, to, now); },
                [this](NmtCommand cmd, TimeUs now) { handleReset(cmd, now); });
  sync_.setHandler([this](std::uint8_t counter, TimeUs now) { handleSync(counter, now); });

  // Hooks first (they are installed once), then the configuration they guard.
  heartbeat_producer_.registerHooks();
  heartbeat_consumer_.registerHooks();
  sync_.registerHooks();
  emcy_.registerHooks();
  for (auto& p : rpdos_) p->registerHooks();
  for (auto& p : tpdos_) p->registerHooks();

  nmt_.subscribe();
  sdo_server_.configure();
  for (auto& p : rpdos_) p->configure();
  for (auto& p : tpdos_) p->configure();
  sync_.configure(0);
  heartbeat_consumer_.configure();
  emcy_.configure();  // last: the EMCY consumer only takes identifiers nobody else uses
}

std::unique_ptr<Node> Node::fromEds(const std::string& eds_path, Transport& transport, std::uint8_t node_id,
                                    NodeOptions options) {
  const EdsFile eds = EdsFile::load(eds_path);
  node_id = resolveNodeId(eds, eds_path, node_id);  // the same check as loadDictionary
  return std::make_unique<Node>(dictionaryFromEds(eds, node_id), node_id, transport, options);
}

void Node::onRpdoTimeout(Rpdo::TimeoutHook cb) {
  for (auto& p : rpdos_) p->setTimeoutHook(cb);
}

// PDOs are created in the order of their numbers, so the number's place is tried first (the cycle looks
// its PDOs up by number); a dictionary with gaps in the numbering falls back to the search.
Rpdo& Node::rpdo(unsigned number) {
  if (number >= 1 && number <= rpdos_.size() && rpdos_[number - 1]->number() == number) return *rpdos_[number - 1];
  for (auto& p : rpdos_) {
    if (p->number() == number) return *p;
  }
  throw OdError("node " + std::to_string(ctx_.node_id) + " has no RPDO" + std::to_string(number));
}

Tpdo& Node::tpdo(unsigned number) {
  if (number >= 1 && number <= tpdos_.size() && tpdos_[number - 1]->number() == number) return *tpdos_[number - 1];
  for (auto& p : tpdos_) {
    if (p->number() == number) return *p;
  }
  throw OdError("node " + std::to_string(ctx_.node_id) + " has no TPDO" + std::to_string(number));
}

void Node::start(TimeUs now) {
  ctx_.now = now;
  // The application may have set communication parameters locally since construction.
  reconfigure(now);
  sync_.restart(now);
  nmt_.bootUp(now);
  if (options_.auto_operational) nmt_.apply(NmtCommand::Start, now);
}

void Node::onFrame(const Frame& frame, TimeUs now) {
  ctx_.now = now;
  ++counters_.rx_frames;
  if (frame.error()) {
    ++counters_.error_frames;
    if (app_.error_frame) app_.error_frame(frame, now);
    return;
  }
  if (frame.remote() || frame.extended()) {
    ++counters_.unsupported_frames;
    return;
  }
  if (ctx_.state == NmtState::Initialising) {
    ++counters_.ignored_in_state;
    return;
  }
  // A node never receives its own frames (no CAN_RAW_RECV_OWN_MSGS, and the in-process bus skips the
  // sender), so one of its own identifiers coming in was sent by somebody else.
  if (transmitsOn(frame.id)) {
    ++counters_.cob_id_collisions;
    if (app_.collision) app_.collision(frame, now);
    return;
  }
  if (!dispatcher_.dispatch(frame, now)) ++counters_.unknown_cob_id;
}

bool Node::transmitsOn(std::uint32_t id) const {
  if (id == kHeartbeatCobIdBase + ctx_.node_id) return true;
  if (emcy_.enabled() && id == emcy_.cobId()) return true;
  if (id == sdo_server_.responseCobId()) return true;
  if (sync_.producer() && id == sync_.cobId()) return true;
  for (const auto& p : tpdos_) {
    if (p->valid() && id == p->cobId()) return true;
  }
  return false;
}

void Node::advance(TimeUs now) {
  ctx_.now = now;
  if (ctx_.state == NmtState::Initialising) return;
  heartbeat_consumer_.advance(now);
  heartbeat_producer_.advance(now);
  sync_.advance(now);
  refreshLive();
  for (Rpdo* p : live_rpdos_) p->advance(now);
  for (Tpdo* p : live_tpdos_) p->advance(now);
  emcy_.advance(now);
  sdo_server_.advance(now);
  sdo_client_.advance(now);
  if (timer_at_ != kNever && now >= timer_at_) {
    timer_at_ = kNever;
    if (app_.timer) app_.timer(now);
  }
}

TimeUs Node::nextDeadline() const {
  if (ctx_.state == NmtState::Initialising) return kNever;
  TimeUs next = std::min({heartbeat_consumer_.nextDeadline(), heartbeat_producer_.nextDeadline(), sync_.nextDeadline(),
                          emcy_.nextDeadline(), sdo_server_.nextDeadline(), sdo_client_.nextDeadline(), timer_at_});
  for (const auto& p : rpdos_)
    if (p->valid()) next = std::min(next, p->nextDeadline());
  for (const auto& p : tpdos_)
    if (p->valid()) next = std::min(next, p->nextDeadline());
  return next;
}

void Node::refreshLive() noexcept {
  if (live_epoch_ == ctx_.pdo_epoch) return;
  live_epoch_ = ctx_.pdo_epoch;
  live_rpdos_.clear();
  live_tpdos_.clear();
  for (auto& p : rpdos_)
    if (p->valid()) live_rpdos_.push_back(p.get());
  for (auto& p : tpdos_)
    if (p->valid()) live_tpdos_.push_back(p.get());
}

void Node::handleSync(std::uint8_t counter, TimeUs now) {
  // Cycle order: SYNC -> latch RPDOs -> application callback -> TPDOs, so the application computes
  // from the inputs of the previous cycle and its outputs leave in this one.
  refreshLive();
  for (Rpdo* p : live_rpdos_) p->onSync(now);
  if (app_.sync) app_.sync(counter, now);
  refreshLive();  // the application may have reconfigured a TPDO
  for (Tpdo* p : live_tpdos_) p->onSync(counter, now);
}

void Node::handleStateChange(NmtState from, NmtState to, TimeUs now) {
  if (to == NmtState::Operational) {
    for (auto& p : tpdos_) p->start(now);
  }
  if (from == NmtState::Operational) {
    for (auto& p : rpdos_) p->reset();
  }
  // A Stopped node has no SDO (CiA 301): a transfer in progress ends there, silently (no frame may
  // go out), and is not resumed by a later NMT start.
  if (to == NmtState::Stopped) sdo_server_.reset();
  if (app_.state) app_.state(from, to, now);
}

void Node::handleReset(NmtCommand cmd, TimeUs now) {
  // Without persistent storage a reset restores the EDS defaults: communication area for reset
  // communication, everything for reset node.
  if (cmd == NmtCommand::ResetNode) od_.restoreDefaults(0x2000, 0xFFFF);
  od_.restoreDefaults(0x1000, 0x1FFF);
  emcy_.clearAll();
  if (app_.reset) app_.reset(cmd, now);
  reconfigure(now);
  nmt_.bootUp(now);
}

void Node::reconfigure(TimeUs now) {
  sdo_server_.reset();
  sdo_client_.abort(kAbortDeviceState);
  for (auto& p : rpdos_) p->reconfigure();
  for (auto& p : tpdos_) p->reconfigure();
  sync_.configure(now);
  heartbeat_producer_.configure(now);
  heartbeat_consumer_.configure();
  emcy_.configure();
}

}  // namespace pamc::canopen
