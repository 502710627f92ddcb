#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "test_util.hpp"
#include "canopen/eds_dictionary.hpp"
#include "canopen/bus.hpp"
#include "canopen/node.hpp"

namespace pamc::canopen::test {
namespace {

// Runs the parser on text and returns the error (fails the test if there is none).
EdsError parseError(const std::string& text) {
  try {
    EdsFile::parse(text, "broken.eds");
  } catch (const EdsError& e) {
    return e;
  }
  ADD_FAILURE() << "no EdsError for:\n" << text;
  return EdsError("", 0, "", "");
}

int lineOf(const std::string& text, const std::string& needle) {
  std::size_t pos = text.find(needle);
  if (pos == std::string::npos) {
    ADD_FAILURE() << "needle not found: " << needle;
    return -1;
  }
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(pos), '\n'));
}

TEST(Eds, ProjectFilesLoadWithTheirValues) {
  ObjectDictionary sensor = loadDictionary(odPath("sensor.eds"));
  EXPECT_EQ(sensor.entry(0x1000, 0).get<std::uint32_t>(), 0x00080196u);
  EXPECT_EQ(sensor.entry(0x1800, 1).get<std::uint32_t>(), 0x182u);  // $NODEID+0x180 with node-ID 2
  EXPECT_EQ(sensor.entry(0x1800, 2).get<std::uint8_t>(), 1);
  EXPECT_EQ(sensor.entry(0x1A00, 1).get<std::uint32_t>(), 0x60040020u);
  EXPECT_EQ(sensor.entry(0x6004, 0).dataType(), DataType::Integer32);
  EXPECT_TRUE(sensor.entry(0x6004, 0).pdoMappable());
  EXPECT_EQ(sensor.entry(0x1008, 0).str(), "pamc linear position sensor");

  ObjectDictionary valve = loadDictionary(odPath("valve.eds"));
  EXPECT_EQ(valve.entry(0x1400, 1).get<std::uint32_t>(), 0x203u);
  EXPECT_EQ(valve.entry(0x1600, 1).get<std::uint32_t>(), 0x64110110u);
  EXPECT_EQ(valve.entry(0x1800, 1).get<std::uint32_t>(), 0x183u);
  EXPECT_EQ(valve.entry(0x1A00, 1).get<std::uint32_t>(), 0x64010110u);
  EXPECT_EQ(valve.entry(0x6411, 1).dataType(), DataType::Integer16);

  EdsFile ctrl_eds = EdsFile::load(odPath("controller.eds"));
  EXPECT_EQ(ctrl_eds.node_id, 1);
  EXPECT_EQ(ctrl_eds.file_info.at("edsversion"), "4.0");
  ObjectDictionary ctrl = dictionaryFromEds(ctrl_eds, 1);
  EXPECT_EQ(ctrl.entry(0x1005, 0).get<std::uint32_t>(), 0x40000080u);
  EXPECT_EQ(ctrl.entry(0x1006, 0).get<std::uint32_t>(), 1000u);
  EXPECT_EQ(ctrl.entry(0x1016, 1).get<std::uint32_t>(), 0x000200FAu);
  EXPECT_EQ(ctrl.entry(0x1016, 2).get<std::uint32_t>(), 0x000300FAu);
  EXPECT_EQ(ctrl.entry(0x1400, 1).get<std::uint32_t>(), 0x182u);
  EXPECT_EQ(ctrl.entry(0x1401, 1).get<std::uint32_t>(), 0x183u);
  EXPECT_EQ(ctrl.entry(0x1800, 1).get<std::uint32_t>(), 0x203u);
  EXPECT_DOUBLE_EQ(ctrl.entry(0x2000, 1).get<double>(), 0.1);
  EXPECT_EQ(ctrl.entry(0x2010, 0).get<std::uint8_t>(), 1);
  EXPECT_EQ(ctrl.object(0x2000)->type, ObjectType::Record);
  // Every manufacturer parameter is REAL32/REAL64 or UNSIGNED8, as the project's rules ask.
  for (const Entry& e : ctrl.entries()) {
    if (e.index() < 0x2000 || e.index() > 0x2FFF || e.subIndex() == 0) continue;
    EXPECT_TRUE(e.dataType() == DataType::Real64 || e.dataType() == DataType::Real32 ||
                e.dataType() == DataType::Unsigned8)
        << entryName(e.index(), e.subIndex());
  }
}

TEST(Eds, NodeIdOverrideChangesNodeIdValues) {
  ObjectDictionary sensor = loadDictionary(odPath("sensor.eds"), 5);
  EXPECT_EQ(sensor.entry(0x1800, 1).get<std::uint32_t>(), 0x185u);
  EXPECT_EQ(sensor.entry(0x1014, 0).get<std::uint32_t>(), 0x85u);
  EXPECT_EQ(sensor.entry(0x1200, 1).get<std::uint32_t>(), 0x605u);
}

TEST(Eds, ValueEncoding) {
  std::vector<std::uint8_t> b;
  EXPECT_EQ(encodeEdsValue("0x10", DataType::Unsigned8, 1, b), "");
  EXPECT_EQ(b, std::vector<std::uint8_t>{0x10});
  EXPECT_EQ(encodeEdsValue("010", DataType::Unsigned8, 1, b), "");  // CiA 306: leading 0 is octal
  EXPECT_EQ(b, std::vector<std::uint8_t>{8});
  EXPECT_EQ(encodeEdsValue("-5", DataType::Integer8, 1, b), "");
  EXPECT_EQ(b, std::vector<std::uint8_t>{0xFB});
  EXPECT_EQ(encodeEdsValue("$NODEID+0x180", DataType::Unsigned32, 3, b), "");
  EXPECT_EQ(b, (std::vector<std::uint8_t>{0x83, 0x01, 0, 0}));
  EXPECT_EQ(encodeEdsValue("0x600+$nodeid", DataType::Unsigned32, 3, b), "");
  EXPECT_EQ(b, (std::vector<std::uint8_t>{0x03, 0x06, 0, 0}));
  EXPECT_EQ(encodeEdsValue("0xFFFF", DataType::Integer16, 1, b), "");
  EXPECT_EQ(b, (std::vector<std::uint8_t>{0xFF, 0xFF}));
  EXPECT_EQ(encodeEdsValue("1.5", DataType::Real32, 1, b), "");
  float f;
  std::memcpy(&f, b.data(), 4);
  EXPECT_EQ(f, 1.5f);
  EXPECT_EQ(encodeEdsValue("0102FF", DataType::OctetString, 1, b), "");
  EXPECT_EQ(b, (std::vector<std::uint8_t>{1, 2, 0xFF}));
  EXPECT_NE(encodeEdsValue("256", DataType::Unsigned8, 1, b), "");
  EXPECT_NE(encodeEdsValue("-1", DataType::Unsigned16, 1, b), "");
  EXPECT_NE(encodeEdsValue("65535", DataType::Integer16, 1, b), "");  // decimal is not a bit pattern
  EXPECT_NE(encodeEdsValue("2", DataType::Boolean, 1, b), "");
  EXPECT_NE(encodeEdsValue("1e40", DataType::Real32, 1, b), "");
  EXPECT_NE(encodeEdsValue("abc", DataType::Real64, 1, b), "");
  EXPECT_NE(encodeEdsValue("$NODEID+$NODEID", DataType::Unsigned32, 1, b), "");
  EXPECT_NE(encodeEdsValue("1+", DataType::Unsigned32, 1, b), "");
}

TEST(Eds, SyntaxErrorReportsFileAndLine) {
  std::string text = makeEds(var(0x2000, "Gain", "0x0011", "rw", "1.0"));
  text.insert(text.find("[2000]"), "this line is not INI\n");
  EdsError e = parseError(text);
  EXPECT_EQ(e.file(), "broken.eds");
  EXPECT_EQ(e.line(), lineOf(text, "this line is not INI"));
  EXPECT_NE(std::string(e.what()).find("broken.eds:" + std::to_string(e.line()) + ": "), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("syntax error"), std::string::npos) << e.what();
}

TEST(Eds, SemanticErrorsNameSectionAndLine) {
  struct Case {
    std::string objects;
    std::string needle;   // text of the reported line
    std::string section;  // reported section
    std::string problem;  // part of the message
  };
  const Case cases[] = {
      {var(0x2000, "Gain", "0xZZ", "rw", "1"), "DataType=0xZZ", "2000", "is not a number"},
      {var(0x2000, "Gain", "0x0099", "rw", "1"), "DataType=0x0099", "2000", "not a supported"},
      {var(0x2000, "Speed", "0x0006", "rw", "fast"), "DefaultValue=fast", "2000", "not a valid UNSIGNED16"},
      {var(0x2000, "Small", "0x0005", "rw", "300"), "DefaultValue=300", "2000", "out of range for UNSIGNED8"},
      {var(0x2000, "Mode", "0x0005", "readwrite", "1"), "AccessType=readwrite", "2000", "is not one of"},
      {var(0x2000, "Mode", "0x0005", "rw", "1", 2), "PDOMapping=2", "2000", "out of range"},
      {var(0x2000, "Gain", "0x0011", "rw", "5", 0, "LowLimit=0\nHighLimit=1\n"), "DefaultValue=5", "2000",
       "above HighLimit"},
      {"[2000]\nObjectType=0x7\nDataType=0x0005\nAccessType=rw\n\n", "[2000]", "2000", "missing key ParameterName"},
      {"[2000]\nParameterName=Rec\nObjectType=0x9\nSubNumber=3\n\n"
       "[2000sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\n\n"
       "[2000sub1]\nParameterName=a\nDataType=0x0011\nAccessType=rw\n\n",
       "SubNumber=3", "2000", "2 sub-object sections exist"},
      {"[2000]\nParameterName=Rec\nObjectType=0x9\nSubNumber=1\n\n"
       "[2000sub0]\nParameterName=n\nDataType=0x0006\nAccessType=ro\nDefaultValue=1\n\n",
       "[2000sub0]", "2000sub0", "must be UNSIGNED8"},
      {"[2001sub1]\nParameterName=a\nDataType=0x0005\nAccessType=rw\n\n", "[2001sub1]", "2001sub1", "no section"},
      {var(0x2000, "Gain", "0x0011", "rw", "1.0\nDataType=0x0011"), "DataType=0x0011\nPDOMapping", "",
       "duplicate key 'DataType' in [2000]"},  // an INI-level problem: the section is named in the text
  };
  for (const Case& c : cases) {
    std::string text = makeEds(c.objects);
    EdsError e = parseError(text);
    EXPECT_EQ(e.line(), lineOf(text, c.needle)) << e.what();
    EXPECT_EQ(e.section(), c.section) << e.what();
    EXPECT_NE(std::string(e.what()).find(c.problem), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).rfind("broken.eds:", 0), 0u) << e.what();
  }
}

TEST(Eds, ObjectListsMustMatchTheSections) {
  std::string unlisted = makeEds("") + var(0x2005, "Orphan", "0x0005", "rw", "0");
  EdsError e = parseError(unlisted);
  EXPECT_EQ(e.section(), "2005");
  EXPECT_NE(std::string(e.what()).find("not listed"), std::string::npos) << e.what();

  std::string text = makeEds(var(0x2000, "Gain", "0x0011", "rw", "1"));
  std::string listed_missing = text;
  listed_missing.replace(listed_missing.find("1=0x2000"), 8, "1=0x2100");
  e = parseError(listed_missing);
  EXPECT_EQ(e.section(), "ManufacturerObjects");
  EXPECT_NE(std::string(e.what()).find("listed object has no section"), std::string::npos) << e.what();

  std::string no_mandatory = text;
  no_mandatory.replace(no_mandatory.find("[MandatoryObjects]"), 18, "[Mandatory]");
  e = parseError(no_mandatory);
  EXPECT_NE(std::string(e.what()).find("MandatoryObjects"), std::string::npos) << e.what();

  std::string dup = text + "[FileInfo]\nFileName=again\n";
  e = parseError(dup);
  EXPECT_EQ(e.line(), lineOf(dup, "[FileInfo]\nFileName=again"));
  EXPECT_NE(std::string(e.what()).find("duplicate section"), std::string::npos) << e.what();

  std::string long_line = text + "; " + std::string(300, 'x') + "\n";
  e = parseError(long_line);
  EXPECT_NE(std::string(e.what()).find("line longer than"), std::string::npos) << e.what();
}

TEST(Eds, CorruptFileOnDiskNamesFileAndLine) {
  const std::string path = ::testing::TempDir() + "pamc_corrupt.eds";
  std::ifstream src(odPath("valve.eds"));
  std::string text((std::istreambuf_iterator<char>(src)), std::istreambuf_iterator<char>());
  std::size_t pos = text.find("DataType=0x0003");  // first INTEGER16 entry
  ASSERT_NE(pos, std::string::npos);
  text.replace(pos, 15, "DataType=INT16");
  {
    std::ofstream out(path);
    out << text;
  }
  try {
    loadDictionary(path);
    FAIL() << "corrupt EDS accepted";
  } catch (const EdsError& e) {
    std::string expect = path + ":" + std::to_string(lineOf(text, "DataType=INT16")) + ": [";
    EXPECT_EQ(std::string(e.what()).rfind(expect, 0), 0u) << e.what();
    EXPECT_NE(std::string(e.what()).find("'INT16' is not a number"), std::string::npos) << e.what();
  }
  std::remove(path.c_str());

  try {
    loadDictionary("/nonexistent/none.eds");
    FAIL() << "missing file accepted";
  } catch (const EdsError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/none.eds: cannot open file"), std::string::npos) << e.what();
  }
}

TEST(Eds, CompactSubObjAndDefaults) {
  std::string text = makeEds(
      "[2000]\nParameterName=Gains\nObjectType=0x8\nDataType=0x0011\nAccessType=rw\nCompactSubObj=3\n"
      "DefaultValue=2.5\nPDOMapping=0\n\n" +
      var(0x2001, "Name", "0x0009", "rw", "abc") + var(0x2002, "Unset", "0x0004", "rw", ""));
  ObjectDictionary od = odFromText(text, 1);
  EXPECT_EQ(od.entry(0x2000, 0).get<std::uint8_t>(), 3);
  EXPECT_DOUBLE_EQ(od.entry(0x2000, 3).get<double>(), 2.5);
  EXPECT_EQ(od.find(0x2000, 4), nullptr);
  EXPECT_EQ(od.entry(0x2001, 0).str(), "abc");
  EXPECT_GE(od.entry(0x2001, 0).capacity(), 32u);
  EXPECT_EQ(od.entry(0x2002, 0).get<std::int32_t>(), 0);
}

TEST(ObjectDictionary, TypedAccessResolvedOnce) {
  ObjectDictionary od = loadDictionary(odPath("sensor.eds"));
  Ref<std::int32_t> pos = od.ref<std::int32_t>(0x6004, 0);
  pos.set(-1234);
  EXPECT_EQ(od.entry(0x6004, 0).get<std::int32_t>(), -1234);
  EXPECT_EQ(pos.get(), -1234);
  EXPECT_THROW(od.ref<std::int16_t>(0x6004, 0), OdError);
  EXPECT_THROW(od.ref<std::int32_t>(0x6004, 1), OdError);
  EXPECT_THROW(od.entry(0x5FFF, 0), OdError);
  od.restoreDefaults(0x6000, 0x6FFF);
  EXPECT_EQ(pos.get(), 0);
}

TEST(ObjectDictionary, RemoteWriteChecksAccessLengthLimitsAndValidators) {
  ObjectDictionary od = loadDictionary(odPath("controller.eds"));
  Entry& kp = od.entry(0x2000, 1);
  int observed = 0;
  od.validate<double>(0x2000, 1, [](double v) { return v > 5.0 ? kAbortValueRange : kSdoOk; });
  od.addObserver(0x2000, 1, [&](Entry&) { ++observed; });
  auto write = [&](Entry& e, double v) {
    std::uint8_t b[8];
    std::memcpy(b, &v, 8);
    return od.remoteWrite(e, b, 8);
  };
  EXPECT_EQ(write(kp, 0.5), kSdoOk);
  EXPECT_EQ(kp.get<double>(), 0.5);
  EXPECT_EQ(observed, 1);
  EXPECT_EQ(write(kp, 8.0), kAbortValueRange);       // application validator (EDS limit: 10)
  EXPECT_EQ(write(kp, 5000.0), kAbortValueTooHigh);  // EDS HighLimit
  EXPECT_EQ(write(kp, -1.0), kAbortValueTooLow);     // EDS LowLimit
  EXPECT_EQ(write(kp, std::nan("")), kAbortValueRange);
  EXPECT_EQ(kp.get<double>(), 0.5);
  EXPECT_EQ(observed, 1);
  std::uint8_t two[2] = {1, 2};
  EXPECT_EQ(od.remoteWrite(kp, two, 2), kAbortLengthTooLow);
  EXPECT_EQ(od.remoteWrite(od.entry(0x1000, 0), two, 2), kAbortReadOnly);
}

// A node built from an EDS meets the same node-ID rule as its dictionary (1..127).
TEST(ObjectDictionary, NodeFromEdsChecksTheNodeIdLikeLoad) {
  VirtualBus bus;
  auto& port = bus.addPort();
  EXPECT_THROW(loadDictionary(odPath("sensor.eds"), 200), EdsError);
  EXPECT_THROW(Node::fromEds(odPath("sensor.eds"), port, 200), EdsError);
  EXPECT_EQ(Node::fromEds(odPath("sensor.eds"), port, 0)->nodeId(), 2);  // [DeviceComissioning] NodeID
}

}  // namespace
}  // namespace pamc::canopen::test
