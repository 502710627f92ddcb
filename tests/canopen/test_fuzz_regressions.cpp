// Regression tests of the fuzzing findings in the CANopen layer (docs/RELIABILITY.md, "Fuzzing"): each
// replays the reproducer the fuzzer found and asserts the corrected behaviour.
#include <sstream>

#include "test_util.hpp"

namespace pamc::canopen::test {
namespace {

using Frames = std::vector<std::string>;

// fuzz_candump: the seconds of a timestamp were accumulated before their number of digits was checked,
// so a long run of digits overflowed a signed 64-bit integer (undefined behaviour) before the line was
// refused.
TEST(FuzzRegression, CandumpTimestampWithTooManyDigitsIsRefusedBeforeItOverflows) {
  CandumpRecord r;
  std::string err;
  EXPECT_FALSE(parseCandumpLine("(17000000000001700000000.000000) vcan0 080#", r, &err));
  EXPECT_EQ(err, "timestamp seconds have more than 12 digits");
  EXPECT_FALSE(parseCandumpLine("(1234567890123.5) vcan0 080#", r, &err));  // 13 digits
  EXPECT_EQ(err, "timestamp seconds have more than 12 digits");
  ASSERT_TRUE(parseCandumpLine("(999999999999.999999) vcan0 080#", r, &err));  // 12 digits still fit
  EXPECT_EQ(r.unix_time_us, 999999999999999999);

  std::istringstream log("(1700000000.000100) vcan0 080#\n(99999999999999999999.0) vcan0 080#\n");
  try {
    readCandumpLog(log, "rig.log");
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "rig.log:2: timestamp seconds have more than 12 digits");
  }
}

// fuzz_eds: a DOMAIN or VISIBLE_STRING without DefaultValue (or with an empty one) made the dictionary
// copy its default from a null pointer (memcpy(dst, nullptr, 0): undefined behaviour).
TEST(FuzzRegression, EmptyStringAndDomainDefaultsBuildEmptyEntries) {
  const std::string eds = makeEds("[2007]\nParameterName=Domain\nObjectType=0x2\nDataType=0x000F\nAccessType=rw\n\n" +
                                  var(0x2008, "Text", "0x0009", "rw", ""));
  ObjectDictionary od = odFromText(eds, 5);
  EXPECT_EQ(od.entry(0x2007, 0).size(), 0u);
  EXPECT_GE(od.entry(0x2007, 0).capacity(), 256u);
  EXPECT_EQ(od.entry(0x2008, 0).size(), 0u);

  // And the node serves them: an empty upload, a download, and the empty default back after a reset.
  Network net;
  net.addText(eds, 5);
  net.startAll();
  EXPECT_EQ(net.exchange("605#4007200000000000"), Frames{"585#4107200000000000"});  // segmented, size 0
  EXPECT_EQ(net.exchange("605#6000000000000000"), Frames{"585#0F00000000000000"});  // last, no data
  EXPECT_EQ(net.exchange("605#2F08200041000000"), Frames{"585#6008200000000000"});
  EXPECT_EQ(net.nodes[0]->od().entry(0x2008, 0).str(), "A");
  net.send("000#8105");  // reset node: manufacturer entries back to their defaults
  EXPECT_EQ(net.nodes[0]->od().entry(0x2008, 0).size(), 0u);
}

// fuzz_sdo_server: a node stopped by NMT in the middle of a segmented transfer sent the SDO timeout
// abort while Stopped, where CiA 301 allows no SDO frames. The transfer now ends silently.
TEST(FuzzRegression, StoppedNodeSendsNoSdoTimeoutAbort) {
  Network net;
  net.addText(makeEds(var(0x2001, "Blob", "0x000F", "rw", "00112233")), 9);
  net.startAll();
  EXPECT_EQ(net.exchange("609#2001200000000000"), Frames{"589#6001200000000000"});  // segmented download
  EXPECT_EQ(net.exchange("609#0031323334353637"), Frames{"589#2000000000000000"});  // first segment
  net.send("000#0209");                                                             // NMT stop node 9
  net.recorder.log.clear();
  net.bus.advanceBy(2'493'200);  // past the 1 s SDO timeout
  EXPECT_TRUE(net.recorder.matching("589#").empty());
  net.send("000#8009");  // back to Pre-operational: the transfer is gone, a segment is refused
  EXPECT_EQ(net.exchange("609#1031323304020000"), Frames{"589#8001200001000405"});
}

// fuzz_sdo_server (long run): a segmented upload begun before an NMT stop was resumed after the next NMT
// start - the server answered the client's next upload segment request with data of the old transfer,
// although the stop had ended SDO communication. Entering Stopped now ends the transfer (silently).
TEST(FuzzRegression, UploadInterruptedByAStopIsNotResumedAfterTheStart) {
  Network net;
  net.addText(makeEds(var(0x2001, "Blob", "0x000F", "rw", "0011223344556677")), 9);
  net.startAll();
  EXPECT_EQ(net.exchange("609#4001200000000000"), Frames{"589#4101200008000000"});  // segmented upload
  EXPECT_EQ(net.exchange("609#6000000000000000"), Frames{"589#0000112233445566"});  // first segment
  net.send("000#0209");                                                             // NMT stop node 9
  EXPECT_TRUE(net.exchange("609#7000000000000000").empty());                        // no SDO when Stopped
  net.send("000#0109");                                                             // NMT start node 9
  EXPECT_EQ(net.exchange("609#7000000000000000"), Frames{"589#8001200001000405"});  // no transfer to resume
}

// fuzz_sdo_server: an SDO write could set the EMCY COB-ID (0x1014) to the node's own SDO request
// identifier (here 0x46464603: bits 11-30 set, identifier 0x603). The node then took every SDO request
// for a frame of another node on its own EMCY identifier and answered none: it could no longer be
// configured. CiA 301 (7.3.5) forbids the restricted CAN-IDs for configurable objects; EMCY, SYNC and
// PDO COB-IDs now refuse them (and EMCY, like SYNC and PDO, identifiers with bits 11-30 set).
TEST(FuzzRegression, EmcyCobIdCannotTakeTheSdoRequestIdentifier) {
  Network net;
  net.addEds(odPath("valve.eds"));
  net.startAll();
  EXPECT_EQ(net.exchange("603#2214100003464646"), Frames{"583#8014100030000906"});  // value range
  net.send("000#0203");
  net.send("000#0100");
  EXPECT_EQ(net.exchange("603#22181000F0000000"), Frames{"583#8018100002000106"});  // answered (read-only)
  EXPECT_EQ(net.exchange("603#2314100003060000"), Frames{"583#8014100030000906"});  // 0x603 restricted
  EXPECT_EQ(net.exchange("603#2314100001070000"), Frames{"583#8014100030000906"});  // 0x701 restricted
  EXPECT_EQ(net.exchange("603#2314100003060080"), Frames{"583#6014100000000000"});  // disabled: allowed
  EXPECT_EQ(net.exchange("603#2314100090000000"), Frames{"583#6014100000000000"});  // 0x090: allowed
  EXPECT_EQ(net.nodes[0]->od().entry(0x1014, 0).get<std::uint32_t>(), 0x90u);
}

TEST(FuzzRegression, SyncAndPdoCobIdsRefuseRestrictedIdentifiers) {
  Network net;
  net.addEds(odPath("controller.eds"));
  net.addEds(odPath("sensor.eds"));
  net.startAll();
  EXPECT_EQ(net.exchange("601#2305100001060040"), Frames{"581#8005100030000906"});  // SYNC on 0x601
  EXPECT_EQ(net.exchange("602#2300180182010080"), Frames{"582#6000180100000000"});  // TPDO1 off
  EXPECT_EQ(net.exchange("602#2300180102060000"), Frames{"582#8000180130000906"});  // on 0x602: refused
  EXPECT_EQ(net.exchange("602#2300180182010000"), Frames{"582#6000180100000000"});  // back on 0x182
}

}  // namespace
}  // namespace pamc::canopen::test
