// The plant file names its kind: the physics plant (src/physics, the default) or the model plant (the
// model's own code with effects, for tests that need a known structure).
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <memory>
#include <string>
#include <vector>

#include "plant/plant.hpp"

using namespace pamc;

TEST(PlantKind, DefaultIsThePhysicsPlant) {
  const auto c = plant::PlantConfig::defaults();
  EXPECT_EQ(c.kind, plant::PlantKind::Physics);
  EXPECT_EQ(c.toJson().at("kind"), "physics");
  EXPECT_EQ(plant::PlantConfig::fromJson(nlohmann::json::object(), "empty.json").kind, plant::PlantKind::Physics);
  // The physics plant moves with the command and stays within its stroke.
  plant::Plant p(c);
  p.reset(-2.0);
  const double low = p.position();
  for (int i = 0; i < 3000; ++i) p.step(2.0);
  const double high = p.position();
  EXPECT_GT(high - low, 5.0) << low << " -> " << high;
  EXPECT_GE(low, c.stroke_min_mm);
  EXPECT_LE(high, c.stroke_max_mm);
}

TEST(PlantKind, ModelKindIsTheModelWithItsForm) {
  const auto c = plant::PlantConfig::fromJson(
      nlohmann::json::parse(R"({"kind":"model","output_form":"printed","effects":{"mass_spring":{"enabled":false}}})"),
      "m.json");
  EXPECT_EQ(c.kind, plant::PlantKind::Model);
  EXPECT_EQ(c.truth.outputForm(), model::OutputForm::Printed);
  EXPECT_FALSE(c.truth.hasEffect("mass_spring"));
  const auto back = plant::PlantConfig::fromJson(c.toJson(), "round trip");
  EXPECT_EQ(back.kind, plant::PlantKind::Model);
  EXPECT_EQ(back.truth.outputForm(), model::OutputForm::Printed);
  EXPECT_EQ(back.truth.params(), c.truth.params());
  EXPECT_EQ(plant::PlantConfig::modelDefaults().truth.outputForm(), model::OutputForm::Aligned);
}

TEST(PlantKind, AModelPlantFileWithoutItsKindIsToldWhatItTakes) {
  try {
    plant::PlantConfig::fromJson(nlohmann::json::parse(R"({"core":{"k":6.0}})"), "old.json");
    FAIL() << "a model plant's keys were taken by the physics plant";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("old.json"), std::string::npos) << what;
    EXPECT_NE(what.find("\"kind\": \"model\""), std::string::npos) << what;
  }
  EXPECT_THROW(plant::PlantConfig::fromJson(nlohmann::json::parse(R"({"kind":"simulink"})"), "k.json"),
               std::invalid_argument);
}

TEST(PlantKind, PhysicsRoundTripsThroughThePlantFile) {
  auto c = plant::PlantConfig::defaults();
  c.Ts = 2e-3;  // a bus's SYNC period
  const auto back = plant::PlantConfig::fromJson(c.toJson(), "dump");
  EXPECT_EQ(back.kind, plant::PlantKind::Physics);
  EXPECT_DOUBLE_EQ(back.Ts, 2e-3);
  EXPECT_EQ(back.physics.toJson().dump(), [&] {
    auto p = c.physics;
    p.Ts = 2e-3;
    return p.toJson().dump();
  }());
}

namespace {

// An external plant's dynamics: a first-order lag y' = (3 u + 10 - y) / 0.05 s, a sensor 0.5 mm off, and a
// log of the commands it was handed.
class LagDynamics final : public plant::ExternalDynamics {
 public:
  explicit LagDynamics(double Ts, std::vector<double>* handed) : Ts_(Ts), handed_(handed) {}
  void reset(double u0, double) noexcept override { y_ = 3.0 * u0 + 10.0; }
  double step(double u, double) noexcept override {
    handed_->push_back(u);
    y_ += (3.0 * u + 10.0 - y_) * (1.0 - std::exp(-Ts_ / 0.05));
    return y_;
  }
  double position() const noexcept override { return y_; }
  double measure() noexcept override { return y_ + 0.5; }

 private:
  double Ts_, y_ = 0.0;
  std::vector<double>* handed_;
};

}  // namespace

TEST(PlantKind, AnExternalPlantIsSteppedThroughItsDynamicsWithAValidCommand) {
  std::vector<double> handed;
  plant::PlantConfig c = plant::PlantConfig::modelDefaults();
  c.kind = plant::PlantKind::External;
  c.external.name = "first-order lag";
  c.external.make = [&](double Ts) { return std::make_unique<LagDynamics>(Ts, &handed); };
  plant::Plant p(c);
  p.reset(1.0);
  EXPECT_DOUBLE_EQ(p.position(), 13.0);
  EXPECT_DOUBLE_EQ(p.measure(), 13.5);  // its own sensor, not the model plant's noise
  for (int i = 0; i < 1000; ++i) p.step(2.0);
  EXPECT_NEAR(p.position(), 16.0, 1e-6);
  p.step(NAN);   // a valve holds mid-range on a nonsense command
  p.step(40.0);  // and stays within its range
  ASSERT_GE(handed.size(), 2u);
  EXPECT_EQ(handed[handed.size() - 2], 0.0);
  EXPECT_EQ(handed.back(), c.u_max);
  EXPECT_TRUE(std::isnan(p.pressure_bar()));
  EXPECT_EQ(c.toJson().at("kind"), "external");
  EXPECT_EQ(c.toJson().at("name"), "first-order lag");
  // A file cannot name it: it is set by a harness.
  EXPECT_THROW(plant::PlantConfig::fromJson(nlohmann::json::parse(R"({"kind":"external"})"), "x.json"),
               std::invalid_argument);
  c.external.make = nullptr;
  EXPECT_THROW(plant::Plant{c}, std::invalid_argument);
}
