#include "canopen/sdo_server.hpp"

#include <algorithm>
#include <cstring>

namespace pamc::canopen {

namespace {
constexpr std::uint16_t kServerSdoParameter = 0x1200;
}  // namespace

void SdoServer::configure() {
  if (subscribed_) ctx_.dispatcher.unsubscribe(rx_id_, this);
  rx_id_ = kSdoRequestBase + ctx_.node_id;
  tx_id_ = kSdoResponseBase + ctx_.node_id;
  if (const Entry* e = ctx_.od.find(kServerSdoParameter, 1)) rx_id_ = e->asUnsigned() & kStandardIdMask;
  if (const Entry* e = ctx_.od.find(kServerSdoParameter, 2)) tx_id_ = e->asUnsigned() & kStandardIdMask;
  buffer_.resize(std::max<std::size_t>(ctx_.od.maxEntrySize(), 8));
  subscribed_ = ctx_.dispatcher.subscribe<&SdoServer::onFrame>(rx_id_, this);
  state_ = State::Idle;
}

void SdoServer::respond(const std::uint8_t (&data)[8]) { ctx_.send(makeFrame(tx_id_, 8, data)); }

void SdoServer::abort(std::uint16_t index, std::uint8_t sub, std::uint32_t code) {
  std::uint8_t d[8] = {0x80, 0, 0, sub, 0, 0, 0, 0};
  putU16(d + 1, index);
  putU32(d + 4, code);
  respond(d);
  ++ctx_.counters.sdo_aborts_sent;
  state_ = State::Idle;
}

std::uint32_t SdoServer::lookup(std::uint16_t index, std::uint8_t sub) {
  entry_ = ctx_.od.find(index, sub);
  index_ = index;
  sub_ = sub;
  if (entry_ != nullptr) return kSdoOk;
  return ctx_.od.hasObject(index) ? kAbortNoSubIndex : kAbortNoObject;
}

void SdoServer::onFrame(const Frame& f, TimeUs now) {
  if (f.len != 8) {  // CiA 301: SDO frames always have 8 data bytes
    ++ctx_.counters.wrong_length;
    return;
  }
  if (!ctx_.communicating()) {
    ++ctx_.counters.ignored_in_state;
    return;
  }
  std::uint8_t ccs = f.data[0] >> 5;
  switch (ccs) {
    case 0: downloadSegment(f, now); break;
    case 1: initiateDownload(f, now); break;
    case 2: initiateUpload(f, now); break;
    case 3: uploadSegment(f, now); break;
    case 4:  // abort from the client: end silently
      ++ctx_.counters.sdo_aborts_received;
      state_ = State::Idle;
      break;
    default:  // block transfer (5, 6) and 7 are not supported
      abort(getU16(f.data + 1), f.data[3], kAbortInvalidCommand);
      break;
  }
}

void SdoServer::initiateDownload(const Frame& f, TimeUs now) {
  std::uint16_t index = getU16(f.data + 1);
  std::uint8_t sub = f.data[3];
  state_ = State::Idle;  // a new initiate replaces any transfer in progress
  std::uint32_t code = lookup(index, sub);
  if (code != kSdoOk) return abort(index, sub, code);
  if (!entry_->writable()) return abort(index, sub, kAbortReadOnly);
  bool expedited = (f.data[0] & 0x02) != 0;
  bool sized = (f.data[0] & 0x01) != 0;
  std::size_t fixed = dataTypeSize(entry_->dataType());
  if (expedited) {
    std::size_t len = sized ? 4 - ((f.data[0] >> 2) & 0x03) : (fixed != 0 && fixed < 4 ? fixed : 4);
    code = ctx_.od.remoteWrite(*entry_, f.data + 4, len);
    if (code != kSdoOk) return abort(index, sub, code);
    std::uint8_t d[8] = {0x60, f.data[1], f.data[2], sub, 0, 0, 0, 0};
    return respond(d);
  }
  size_indicated_ = sized;
  size_ = sized ? getU32(f.data + 4) : 0;
  if (sized) {
    // Refuse a wrong size before any segment is sent.
    if (fixed != 0 && size_ > fixed) return abort(index, sub, kAbortLengthTooHigh);
    if (fixed != 0 && size_ < fixed) return abort(index, sub, kAbortLengthTooLow);
    if (size_ > entry_->capacity()) return abort(index, sub, kAbortLengthTooHigh);
  }
  state_ = State::Download;
  offset_ = 0;
  toggle_ = 0;
  deadline_us_ = now + timeout_us_;
  std::uint8_t d[8] = {0x60, f.data[1], f.data[2], sub, 0, 0, 0, 0};
  respond(d);
}

void SdoServer::downloadSegment(const Frame& f, TimeUs now) {
  if (state_ != State::Download) return abort(index_, sub_, kAbortInvalidCommand);
  std::uint8_t t = (f.data[0] >> 4) & 1;
  if (t != toggle_) return abort(index_, sub_, kAbortToggleBit);
  std::size_t n = 7 - ((f.data[0] >> 1) & 0x07);
  bool last = (f.data[0] & 0x01) != 0;
  if (offset_ + n > entry_->capacity() || offset_ + n > buffer_.size()) {
    return abort(index_, sub_, kAbortLengthTooHigh);
  }
  std::memcpy(buffer_.data() + offset_, f.data + 1, n);
  offset_ += n;
  if (last) {
    if (size_indicated_ && offset_ != size_) return abort(index_, sub_, kAbortLengthMismatch);
    std::uint32_t code = ctx_.od.remoteWrite(*entry_, buffer_.data(), offset_);
    if (code != kSdoOk) return abort(index_, sub_, code);
    state_ = State::Idle;
  } else {
    deadline_us_ = now + timeout_us_;
  }
  std::uint8_t d[8] = {static_cast<std::uint8_t>(0x20 | (t << 4)), 0, 0, 0, 0, 0, 0, 0};
  toggle_ ^= 1;
  respond(d);
}

void SdoServer::initiateUpload(const Frame& f, TimeUs now) {
  std::uint16_t index = getU16(f.data + 1);
  std::uint8_t sub = f.data[3];
  state_ = State::Idle;
  std::uint32_t code = lookup(index, sub);
  if (code != kSdoOk) return abort(index, sub, code);
  std::size_t len = 0;
  // Snapshot the value so a segmented upload is consistent even if the application changes it.
  code = ctx_.od.remoteRead(*entry_, buffer_.data(), buffer_.size(), len);
  if (code != kSdoOk) return abort(index, sub, code);
  std::uint8_t d[8] = {0, f.data[1], f.data[2], sub, 0, 0, 0, 0};
  if (len >= 1 && len <= 4) {
    d[0] = static_cast<std::uint8_t>(0x43 | ((4 - len) << 2));
    std::memcpy(d + 4, buffer_.data(), len);
    return respond(d);
  }
  d[0] = 0x41;
  putU32(d + 4, static_cast<std::uint32_t>(len));
  size_ = len;
  offset_ = 0;
  toggle_ = 0;
  state_ = State::Upload;
  deadline_us_ = now + timeout_us_;
  respond(d);
}

void SdoServer::uploadSegment(const Frame& f, TimeUs now) {
  if (state_ != State::Upload) return abort(index_, sub_, kAbortInvalidCommand);
  std::uint8_t t = (f.data[0] >> 4) & 1;
  if (t != toggle_) return abort(index_, sub_, kAbortToggleBit);
  std::size_t n = std::min<std::size_t>(7, size_ - offset_);
  bool last = offset_ + n >= size_;
  std::uint8_t d[8] = {static_cast<std::uint8_t>((t << 4) | ((7 - n) << 1) | (last ? 1 : 0)), 0, 0, 0, 0, 0, 0, 0};
  std::memcpy(d + 1, buffer_.data() + offset_, n);
  offset_ += n;
  toggle_ ^= 1;
  if (last)
    state_ = State::Idle;
  else
    deadline_us_ = now + timeout_us_;
  respond(d);
}

void SdoServer::advance(TimeUs now) {
  if (state_ == State::Idle || now < deadline_us_) return;
  // A Stopped node sends no SDO frame (CiA 301): the transfer ends without an abort, as the client's does.
  if (!ctx_.communicating()) {
    state_ = State::Idle;
    return;
  }
  abort(index_, sub_, kAbortTimeout);
}

TimeUs SdoServer::nextDeadline() const { return state_ == State::Idle ? kNever : deadline_us_; }

}  // namespace pamc::canopen
