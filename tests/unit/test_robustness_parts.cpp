// pamc robustness in parts (--shard I/N, --pairs-of, --merge): the merged files are a single run's.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "io/measurement.hpp"
#include "io/text.hpp"
#include "sim/robustness.hpp"

using namespace pamc;
namespace fs = std::filesystem;

namespace {

std::string slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  EXPECT_TRUE(f.good()) << path;
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

sim::RobustnessAxis axisNamed(const std::vector<sim::RobustnessAxis>& axes, const std::string& name) {
  for (const auto& a : axes)
    if (a.name == name) return a;
  throw std::logic_error("no axis " + name);
}

// Two axes of two values, one of them the model's (an identification in a part), shortened trajectories
// and the fast fit: three axis cells and the grid's corner.
sim::RobustnessSettings shortSettings(const std::string& out_dir) {
  sim::RobustnessSettings s;
  s.out_dir = out_dir;
  s.figures = false;
  s.duration_scale = 0.1;
  s.fit = ident::FitSettings::forMethod(ident::FitMethod::MultiStart);
  const auto all = sim::robustnessAxes(s.plant);
  auto flow = axisNamed(all, "flow"), model = axisNamed(all, "model");
  flow.values = {0.4 * flow.nominal, flow.nominal};
  model.values = {1.4, model.nominal};
  s.axes = {flow, model};
  s.threads = 1;
  return s;
}

// Every part of each phase in its own folder, merged into `out`.
void runInParts(const sim::RobustnessSettings& base, int n, const std::string& out) {
  std::vector<nlohmann::json> parts;
  for (int i = 1; i <= n; ++i) {
    sim::RobustnessSettings s = base;
    s.out_dir = out + "_axes" + std::to_string(i);
    s.shard = {i, n};
    sim::runRobustnessCells(s);
    parts.push_back(sim::readRobustnessCells(s.out_dir));
  }
  sim::RobustnessSettings o = base;
  o.out_dir = out;
  const auto first = sim::mergeRobustness(parts, o);
  ASSERT_TRUE(first.pairs_pending);
  ASSERT_FALSE(fs::exists(out + "/grid.csv"));
  const auto axes = sim::readRobustnessCells(out);
  parts.clear();
  for (int i = 1; i <= n; ++i) {
    sim::RobustnessSettings s;
    s.out_dir = out + "_pairs" + std::to_string(i);
    s.shard = {i, n};
    sim::runRobustnessCells(s, &axes);
    parts.push_back(sim::readRobustnessCells(s.out_dir));
  }
  EXPECT_FALSE(sim::mergeRobustness(parts, o).pairs_pending);
}

nlohmann::json withoutTiming(nlohmann::json j) {
  for (const char* k : {"seconds", "threads", "shards"}) j.erase(k);
  return j;
}

}  // namespace

TEST(RobustnessParts, ShardParsesIOverNAndRefusesTheRest) {
  const auto p = sim::parseShard("2/3");
  EXPECT_EQ(p.index, 2);
  EXPECT_EQ(p.count, 3);
  for (const char* bad : {"0/3", "4/3", "2", "2/", "/3", "a/b", "2/3x", "1/0"}) {
    EXPECT_THROW(sim::parseShard(bad), std::invalid_argument) << bad;
  }
}

// The CSVs byte for byte and summary.json but for its timing, for N = 1, 2, 3.
TEST(RobustnessParts, MergedPartsWriteTheFilesOfOneRun) {
  const std::string root = (fs::temp_directory_path() / "pamc_test_robustness_parts").string();
  fs::remove_all(root);
  fs::create_directories(root);
  const auto base = shortSettings(root + "/single");
  const auto single = sim::runRobustness(base);
  ASSERT_EQ(single.variants, 4);
  const std::vector<std::string> csvs = {"axis_flow.csv", "axis_model.csv", "grid.csv", "ident_A1.40.csv",
                                         "ident_A" + io::fmt("%.2f", sim::kIdentAmplitude) + ".csv"};
  for (int n : {1, 2, 3}) {
    const std::string out = root + "/n" + std::to_string(n);
    runInParts(base, n, out);
    for (const auto& f : csvs) EXPECT_EQ(slurp(out + "/" + f), slurp(base.out_dir + "/" + f)) << f << ", N = " << n;
    const auto merged = nlohmann::json::parse(slurp(out + "/summary.json"));
    EXPECT_EQ(withoutTiming(merged), withoutTiming(single.json)) << "N = " << n;
    EXPECT_EQ(merged.at("shards").get<int>(), n);
  }
}

// A missing part, a part given twice, parts of other settings: refused, naming them; nothing written.
TEST(RobustnessParts, TheMergeRefusesAnIncompleteOrMixedSet) {
  const std::string root = (fs::temp_directory_path() / "pamc_test_robustness_refuse").string();
  fs::remove_all(root);
  fs::create_directories(root);
  auto base = shortSettings(root + "/p");
  base.axes.pop_back();  // flow only: no identification beyond the nominal model
  base.grid = false;
  std::vector<nlohmann::json> parts;
  for (int i = 1; i <= 2; ++i) {
    auto s = base;
    s.out_dir = root + "/p" + std::to_string(i);
    s.shard = {i, 2};
    sim::runRobustnessCells(s);
    parts.push_back(sim::readRobustnessCells(s.out_dir));
  }
  auto other = base;
  other.out_dir = root + "/other";
  other.shard = {2, 2};
  other.ctrl.kp *= 2.0;
  sim::runRobustnessCells(other);
  auto out = base;
  out.out_dir = root + "/merged";
  auto refused = [&](const std::vector<nlohmann::json>& docs, const std::string& says) {
    try {
      sim::mergeRobustness(docs, out);
      ADD_FAILURE() << "merged; expected: " << says;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(out.out_dir));
  };
  refused({parts[0]}, "part 2/2 of the axes is missing");
  refused({parts[0], parts[0]}, "part 1/2 given twice");
  refused({parts[0], sim::readRobustnessCells(root + "/other")}, "'controller' differs");
  EXPECT_THROW(sim::readRobustnessCells(root + "/nowhere"), io::InputError);
  sim::mergeRobustness(parts, out);
  EXPECT_TRUE(fs::exists(out.out_dir + "/axis_flow.csv"));
}
