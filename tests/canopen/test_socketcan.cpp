// SocketCAN transport and event loop. No CAN interface exists here, so the transport adopts one end of
// a datagram socketpair that carries struct can_frame records, and the test plays the bus at the other.
#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <system_error>
#include <thread>

#include "canopen/eds_dictionary.hpp"
#include "canopen/event_loop.hpp"
#include "canopen/socketcan.hpp"
#include "test_util.hpp"

namespace pamc::canopen::test {
namespace {

struct SocketPair {
  SocketPair() {
    if (::socketpair(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0, fds) != 0)
      throw std::system_error(errno, std::generic_category());
    ::fcntl(fds[1], F_SETFL, ::fcntl(fds[1], F_GETFL, 0) | O_NONBLOCK);
  }
  ~SocketPair() { ::close(fds[1]); }  // fds[0] belongs to the transport
  int fds[2] = {-1, -1};
};

void writeCan(int fd, canid_t id, std::initializer_list<std::uint8_t> data) {
  can_frame cf{};
  cf.can_id = id;
  cf.can_dlc = static_cast<std::uint8_t>(data.size());
  std::copy(data.begin(), data.end(), cf.data);
  ASSERT_EQ(::write(fd, &cf, sizeof cf), static_cast<ssize_t>(sizeof cf));
}

std::vector<std::string> readAll(int fd) {
  std::vector<std::string> out;
  can_frame cf{};
  while (::read(fd, &cf, sizeof cf) == static_cast<ssize_t>(sizeof cf)) {
    Frame f = makeFrame(cf.can_id & CAN_SFF_MASK, cf.can_dlc, cf.data);
    out.push_back(formatFrame(f));
  }
  return out;
}

TEST(SocketCan, MissingInterfaceIsNamedInTheError) {
  try {
    SocketCanTransport t("pamcnosuch0");
    FAIL() << "opened a missing interface";
  } catch (const std::system_error& e) {
    EXPECT_NE(std::string(e.what()).find("SocketCAN pamcnosuch0"), std::string::npos) << e.what();
  }
}

TEST(SocketCan, FullTransmitQueueIsRetriedOnPolloutWithoutLoss) {
  SocketPair pair;
  SocketCanOptions options;
  options.tx_queue_capacity = 4096;
  auto can = SocketCanTransport::adopt(pair.fds[0], "pair0", options);
  constexpr int kFrames = 3000;
  for (int i = 0; i < kFrames; ++i) {
    Frame f = makeFrame(static_cast<std::uint32_t>(0x100 + i % 0x600), 4);
    putU32(f.data, static_cast<std::uint32_t>(i));
    ASSERT_TRUE(can->send(f)) << i;
  }
  // The peer did not read: the socket filled up and the transport queued instead of dropping.
  ASSERT_GT(can->stats().tx_queued, 0u);
  ASSERT_TRUE(can->hasPendingTx());
  std::vector<std::uint32_t> received;
  auto drain = [&] {
    can_frame cf{};
    while (::read(pair.fds[1], &cf, sizeof cf) == static_cast<ssize_t>(sizeof cf)) received.push_back(getU32(cf.data));
  };
  for (int round = 0; round < 10000 && can->hasPendingTx(); ++round) {
    drain();
    pollfd p{can->fd(), POLLOUT, 0};
    ASSERT_EQ(::poll(&p, 1, 1000), 1);
    can->flush();
  }
  drain();
  EXPECT_FALSE(can->hasPendingTx());
  ASSERT_EQ(received.size(), static_cast<std::size_t>(kFrames));
  for (int i = 0; i < kFrames; ++i) ASSERT_EQ(received[static_cast<std::size_t>(i)], static_cast<std::uint32_t>(i));
  EXPECT_EQ(can->stats().tx_dropped, 0u);
  EXPECT_EQ(can->stats().tx_frames, static_cast<std::uint64_t>(kFrames));
}

TEST(SocketCan, QueueOverflowIsReportedAndCounted) {
  SocketPair pair;
  SocketCanOptions options;
  options.tx_queue_capacity = 4;
  auto can = SocketCanTransport::adopt(pair.fds[0], "pair0", options);
  int refused = 0;
  for (int i = 0; i < 3000; ++i) refused += can->send(makeFrame(0x181, 1)) ? 0 : 1;
  EXPECT_GT(refused, 0);
  EXPECT_EQ(can->stats().tx_dropped, static_cast<std::uint64_t>(refused));
}

// Fills the peer's socket with frames without a deadline until the transport has to queue one: that
// frame sits at the head of the queue, refused, as behind a flooded CAN interface. Returns how many
// frames reached the socket before it.
int fillUntilQueued(SocketCanTransport& can) {
  int written = 0;
  while (can.stats().tx_queued == 0) {
    Frame f = makeFrame(0x701, 1);
    EXPECT_TRUE(can.send(f));
    ++written;
  }
  return written - 1;
}

std::vector<std::string> drainAndFlush(SocketCanTransport& can, int fd) {
  std::vector<std::string> out;
  for (int round = 0; round < 1000; ++round) {
    auto got = readAll(fd);
    out.insert(out.end(), got.begin(), got.end());
    if (!can.hasPendingTx() && got.empty()) break;
    can.flush();
  }
  return out;
}

TEST(SocketCan, FrameWithoutDeadlineTakesTheRoomOfTheOldestFrameWithOne) {
  // An EMCY sent while the queue is full of SYNCs and synchronous PDOs waiting for the interface is
  // not dropped: the oldest frame with a deadline (of no use late anyway) makes room.
  SocketPair pair;
  SocketCanOptions options;
  options.tx_queue_capacity = 4;
  auto can = SocketCanTransport::adopt(pair.fds[0], "pair0", options);
  const int before = fillUntilQueued(*can);
  const TimeUs later = monotonicNowUs() + 60'000'000;
  ASSERT_TRUE(can->sendUntil(makeFrame(0x080, 0), later));
  ASSERT_TRUE(can->sendUntil(makeFrame(0x203, 2), later));
  ASSERT_TRUE(can->sendUntil(makeFrame(0x080, 1), later));
  ASSERT_EQ(can->queued(), 4u);
  Frame emcy = makeFrame(0x081, 8);
  putU16(emcy.data, 0x8110);
  EXPECT_TRUE(can->send(emcy));
  EXPECT_EQ(can->stats().tx_dropped, 0u);
  EXPECT_EQ(can->stats().tx_expired, 1u);
  EXPECT_EQ(can->expiredCount(), 1u);  // the node sees the loss (CAN overrun)
  // Queue of frames without a deadline only: the next one is refused and counted, as before.
  EXPECT_TRUE(can->send(makeFrame(0x701, 1)));  // takes the place of 0x203
  EXPECT_TRUE(can->send(makeFrame(0x701, 1)));  // ... of the second SYNC
  EXPECT_FALSE(can->send(makeFrame(0x701, 1)));
  EXPECT_EQ(can->stats().tx_dropped, 1u);
  auto frames = drainAndFlush(*can, pair.fds[1]);
  ASSERT_EQ(frames.size(), static_cast<std::size_t>(before + 4));
  // In the order sent, less the frames that made room.
  EXPECT_EQ(frames[static_cast<std::size_t>(before)], "701#00");
  EXPECT_EQ(frames[static_cast<std::size_t>(before) + 1], "081#1081000000000000");
  EXPECT_EQ(frames[static_cast<std::size_t>(before) + 2], "701#00");
  EXPECT_EQ(frames[static_cast<std::size_t>(before) + 3], "701#00");
  EXPECT_FALSE(can->hasPendingTx());
}

TEST(SocketCan, ExpiredFramesBehindARefusedHeadAreRemovedWhenRoomIsNeeded) {
  SocketPair pair;
  SocketCanOptions options;
  options.tx_queue_capacity = 4;
  auto can = SocketCanTransport::adopt(pair.fds[0], "pair0", options);
  const int before = fillUntilQueued(*can);
  const TimeUs past = monotonicNowUs() - 1;
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(can->sendUntil(makeFrame(0x080, 0), past));
  // Full; a frame with a deadline finds room too, once the stale ones are gone.
  EXPECT_TRUE(can->sendUntil(makeFrame(0x203, 2), monotonicNowUs() + 60'000'000));
  EXPECT_EQ(can->stats().tx_expired, 3u);
  EXPECT_EQ(can->stats().tx_dropped, 0u);
  EXPECT_EQ(can->queued(), 2u);
  auto frames = drainAndFlush(*can, pair.fds[1]);
  ASSERT_EQ(frames.size(), static_cast<std::size_t>(before + 2));
  EXPECT_EQ(frames.back(), "203#0000");
}

TEST(SocketCan, EventLoopRunsANodeInRealTime) {
  SocketPair pair;
  auto can = SocketCanTransport::adopt(pair.fds[0], "pair0");
  Node node(loadDictionary(odPath("controller.eds")), 1, *can);
  std::vector<Frame> error_frames;
  node.onErrorFrame([&](const Frame& f, TimeUs) { error_frames.push_back(f); });
  int tapped_rx = 0;
  can->setTap([&](const Frame&, TimeUs unix_us, bool tx) {
    tapped_rx += tx ? 0 : 1;
    EXPECT_GT(unix_us, 1'600'000'000'000'000);  // wall-clock time for candump logs
  });
  writeCan(pair.fds[1], 0x601, {0x40, 0x17, 0x10, 0x00, 0, 0, 0, 0});  // SDO upload 0x1017
  writeCan(pair.fds[1], CAN_ERR_FLAG | CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0});
  const TimeUs start = monotonicNowUs();
  node.start(start);
  EventLoop loop(*can, node);
  loop.runFor(50'000);
  auto frames = readAll(pair.fds[1]);
  ASSERT_FALSE(frames.empty());
  EXPECT_EQ(frames[0], "701#00");
  EXPECT_NE(std::find(frames.begin(), frames.end(), "581#4B17100064000000"), frames.end());
  auto syncs = std::count(frames.begin(), frames.end(), "080#");
  EXPECT_GE(syncs, 10);  // 1 ms period; a loaded machine may skip some, never add any
  EXPECT_LE(syncs, 51);
  EXPECT_EQ((node.sync().nextDeadline() - start) % 1000, 0);  // still on the grid
  ASSERT_EQ(error_frames.size(), 1u);
  EXPECT_EQ(error_frames[0].id, static_cast<std::uint32_t>(CAN_ERR_BUSOFF));
  EXPECT_EQ(node.counters().error_frames, 1u);
  EXPECT_EQ(tapped_rx, 2);
}

TEST(SocketCan, EventLoopStopsFromAnotherThread) {
  SocketPair pair;
  auto can = SocketCanTransport::adopt(pair.fds[0], "pair0");
  Node node(loadDictionary(odPath("sensor.eds")), 2, *can);
  node.start(monotonicNowUs());
  EventLoop loop(*can, node);
  auto t0 = std::chrono::steady_clock::now();
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    loop.stop();
  });
  loop.run();
  stopper.join();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(5));
  EXPECT_EQ(readAll(pair.fds[1]).front(), "702#00");
}

}  // namespace
}  // namespace pamc::canopen::test
