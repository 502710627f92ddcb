// The plant file names its kind: the physics plant (src/physics, the default) or the model plant (the
// model's own code with effects, for tests that need a known structure).
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

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
