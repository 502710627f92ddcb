#include "canopen/sdo_client.hpp"

#include <algorithm>

#include "canopen/sdo_server.hpp"

namespace pamc::canopen {

SdoClient::SdoClient(NodeContext& ctx, TimeUs timeout_us, std::size_t buffer_size)
    : ctx_(ctx), timeout_us_(timeout_us), buffer_(std::max<std::size_t>(buffer_size, 8)) {}

bool SdoClient::begin(std::uint8_t server_node, std::uint16_t index, std::uint8_t sub, Callback done, State state) {
  if (state_ != State::Idle || server_node == 0 || server_node > 127) return false;
  tx_id_ = kSdoRequestBase + server_node;
  rx_id_ = kSdoResponseBase + server_node;
  if (!ctx_.dispatcher.subscribe<&SdoClient::onFrame>(rx_id_, this)) return false;
  index_ = index;
  sub_ = sub;
  done_ = std::move(done);
  state_ = state;
  toggle_ = 0;
  offset_ = 0;
  last_sent_ = false;
  deadline_us_ = ctx_.now + timeout_us_;
  return true;
}

bool SdoClient::download(std::uint8_t server_node, std::uint16_t index, std::uint8_t sub, const std::uint8_t* data,
                         std::size_t len, Callback done) {
  if (len > buffer_.size() || len > 0xFFFFFFFFu) return false;
  if (!begin(server_node, index, sub, std::move(done), State::DownloadInitiate)) return false;
  std::memcpy(buffer_.data(), data, len);
  size_ = len;
  std::uint8_t d[8] = {0, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0};
  if (len >= 1 && len <= 4) {
    d[0] = static_cast<std::uint8_t>(0x23 | ((4 - len) << 2));  // expedited, size indicated
    std::memcpy(d + 4, data, len);
  } else {
    d[0] = 0x21;  // segmented, size indicated
    putU32(d + 4, static_cast<std::uint32_t>(len));
  }
  request(d);
  return true;
}

bool SdoClient::upload(std::uint8_t server_node, std::uint16_t index, std::uint8_t sub, Callback done) {
  if (!begin(server_node, index, sub, std::move(done), State::UploadInitiate)) return false;
  std::uint8_t d[8] = {0x40, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0};
  request(d);
  return true;
}

void SdoClient::request(const std::uint8_t (&data)[8]) { ctx_.send(makeFrame(tx_id_, 8, data)); }

void SdoClient::finish(std::uint32_t code, const std::uint8_t* data, std::size_t len) {
  ctx_.dispatcher.unsubscribe(rx_id_, this);
  state_ = State::Idle;
  // Move the callback out first: it may start the next transfer.
  Callback cb = std::move(done_);
  done_ = nullptr;
  if (cb) cb(code, data, len);
}

void SdoClient::fail(std::uint32_t code) {
  std::uint8_t d[8] = {0x80, static_cast<std::uint8_t>(index_), static_cast<std::uint8_t>(index_ >> 8), sub_, 0, 0, 0,
                       0};
  putU32(d + 4, code);
  request(d);
  ++ctx_.counters.sdo_aborts_sent;
  finish(code, nullptr, 0);
}

void SdoClient::abort(std::uint32_t code) {
  if (state_ != State::Idle) fail(code);
}

void SdoClient::sendSegment() {
  std::size_t n = std::min<std::size_t>(7, size_ - offset_);
  last_sent_ = offset_ + n >= size_;
  std::uint8_t d[8] = {
      static_cast<std::uint8_t>((toggle_ << 4) | ((7 - n) << 1) | (last_sent_ ? 1 : 0)), 0, 0, 0, 0, 0, 0, 0};
  std::memcpy(d + 1, buffer_.data() + offset_, n);
  offset_ += n;
  request(d);
}

void SdoClient::onFrame(const Frame& f, TimeUs now) {
  if (state_ == State::Idle) return;
  if (f.len != 8) {
    ++ctx_.counters.wrong_length;
    return;
  }
  std::uint8_t cmd = f.data[0];
  std::uint8_t scs = cmd >> 5;
  if (scs == 4) {
    ++ctx_.counters.sdo_aborts_received;
    return finish(getU32(f.data + 4), nullptr, 0);
  }
  deadline_us_ = now + timeout_us_;
  switch (state_) {
    case State::DownloadInitiate:
      if (scs != 3) return fail(kAbortInvalidCommand);
      if (getU16(f.data + 1) != index_ || f.data[3] != sub_) return fail(kAbortGeneral);
      if (size_ >= 1 && size_ <= 4) return finish(kSdoOk, nullptr, 0);
      state_ = State::DownloadSegment;
      return sendSegment();
    case State::DownloadSegment:
      if (scs != 1) return fail(kAbortInvalidCommand);
      if (((cmd >> 4) & 1) != toggle_) return fail(kAbortToggleBit);
      if (last_sent_) return finish(kSdoOk, nullptr, 0);
      toggle_ ^= 1;
      return sendSegment();
    case State::UploadInitiate: {
      if (scs != 2) return fail(kAbortInvalidCommand);
      if (getU16(f.data + 1) != index_ || f.data[3] != sub_) return fail(kAbortGeneral);
      bool expedited = (cmd & 0x02) != 0;
      size_indicated_ = (cmd & 0x01) != 0;
      if (expedited) {
        std::size_t len = size_indicated_ ? 4 - ((cmd >> 2) & 0x03) : 4;
        std::memcpy(buffer_.data(), f.data + 4, len);
        return finish(kSdoOk, buffer_.data(), len);
      }
      size_ = size_indicated_ ? getU32(f.data + 4) : 0;
      if (size_ > buffer_.size()) return fail(kAbortOutOfMemory);
      state_ = State::UploadSegment;
      std::uint8_t d[8] = {0x60, 0, 0, 0, 0, 0, 0, 0};
      return request(d);
    }
    case State::UploadSegment: {
      if (scs != 0) return fail(kAbortInvalidCommand);
      if (((cmd >> 4) & 1) != toggle_) return fail(kAbortToggleBit);
      std::size_t n = 7 - ((cmd >> 1) & 0x07);
      if (offset_ + n > buffer_.size()) return fail(kAbortOutOfMemory);
      std::memcpy(buffer_.data() + offset_, f.data + 1, n);
      offset_ += n;
      if ((cmd & 0x01) != 0) {
        if (size_indicated_ && offset_ != size_) return fail(kAbortLengthMismatch);
        return finish(kSdoOk, buffer_.data(), offset_);
      }
      toggle_ ^= 1;
      std::uint8_t d[8] = {static_cast<std::uint8_t>(0x60 | (toggle_ << 4)), 0, 0, 0, 0, 0, 0, 0};
      return request(d);
    }
    case State::Idle: break;
  }
}

void SdoClient::advance(TimeUs now) {
  if (state_ != State::Idle && now >= deadline_us_) fail(kAbortTimeout);
}

}  // namespace pamc::canopen
