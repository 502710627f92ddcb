#include "plant/plant.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

#include "io/json_fields.hpp"

namespace pamc::plant {

namespace {
// Default truth. Calibrated by `pamc calibrate` (see docs/CALIBRATION.md): a Bouc-Wen model
// identified on u0 misses it by about the RMSE of the paper's Table 1.
const char* const kDefaultJson = R"({
  "Ts": 0.001,
  "core": {"k": 9.0, "rho": 1.25, "b": 18.0, "alpha": 1.0, "beta": 0.35, "gamma": 0.25},
  "effects": {
    "pressure_lag":        {"enabled": true, "tau": 0.2, "slew": 60.0},
    "load":                {"enabled": true, "compliance": 0.06},
    "saturation":          {"enabled": true, "knee": 18.0, "width": 18.0},
    "friction_hysteresis": {"enabled": true, "zmax": 1.5, "delta": 3.0},
    "mass_spring":         {"enabled": true, "fn": 6.0, "zeta": 0.4}
  },
  "stroke":  {"enabled": true, "min_mm": 0.0, "max_mm": 40.0},
  "sensor":  {"noise": true, "noise_std_mm": 0.004, "quantization": true, "quantum_mm": 0.001},
  "valve":   {"u_min": -5.0, "u_max": 5.0, "pressure_max_bar": 8.0},
  "seed": 1
})";

using namespace io::json_fields;

void apply(PlantConfig& c, const nlohmann::json& j, const std::string& where) {
  onlyKeys(j, {"kind", "Ts", "core", "output_form", "effects", "stroke", "sensor", "valve", "seed"}, where);
  if (j.contains("output_form")) {
    model::OutputForm f{};
    if (!j["output_form"].is_string() || !model::parseOutputForm(j["output_form"].get<std::string>(), f))
      fail(where, "'output_form' must be \"aligned\" or \"printed\"");
    c.truth.setOutputForm(f);
  }
  if (j.contains("Ts")) {
    c.Ts = number(j["Ts"], "Ts", where);
    if (!(c.Ts >= 1e-5 && c.Ts <= 1.0)) fail(where, "'Ts' must be between 1e-5 and 1 s");
  }
  if (j.contains("core")) {
    const auto& k = j["core"];
    onlyKeys(k, {"k", "rho", "b", "alpha", "beta", "gamma"}, where + ": core");
    auto& p = c.truth.core();
    if (k.contains("k")) p.k = number(k["k"], "k", where);
    if (k.contains("rho")) p.rho = number(k["rho"], "rho", where);
    if (k.contains("b")) p.b = number(k["b"], "b", where);
    if (k.contains("alpha")) p.alpha = number(k["alpha"], "alpha", where);
    if (k.contains("beta")) p.beta = number(k["beta"], "beta", where);
    if (k.contains("gamma")) p.gamma = number(k["gamma"], "gamma", where);
  }
  if (j.contains("effects")) {
    const auto& e = j["effects"];
    if (!e.is_object()) fail(where, "'effects' must be an object of effect name -> settings");
    // Rebuild the effect list: listed effects keep the old values unless overridden.
    model::Model m(c.truth.core());
    m.setOutputForm(c.truth.outputForm());
    std::vector<std::pair<std::string, std::vector<std::pair<std::string, double>>>> keep;
    for (int i = 0; i < c.truth.numEffects(); ++i) {
      const auto& eff = c.truth.effect(i);
      std::vector<std::pair<std::string, double>> ps;
      for (size_t q = 0; q < eff.params().size(); ++q)
        ps.emplace_back(eff.params()[q].name, c.truth.effectParams(i)[q]);
      keep.emplace_back(eff.name(), ps);
    }
    std::set<std::string> enabled;
    for (const auto& kv : keep) enabled.insert(kv.first);
    for (auto it = e.begin(); it != e.end(); ++it) {
      const std::string w = where + ": effects." + it.key();
      (void)model::makeEffect(it.key());  // throws with the list of known names
      if (!it.value().is_object()) fail(w, "expected an object");
      bool on = true;
      if (it.value().contains("enabled")) on = flag(it.value()["enabled"], "enabled", w);
      if (on)
        enabled.insert(it.key());
      else
        enabled.erase(it.key());
    }
    for (const auto& name : enabled) {
      try {
        m.addEffect(name);
      } catch (const std::invalid_argument& ex) {
        fail(where + ": effects", ex.what());
      }
    }
    for (const auto& kv : keep)
      if (enabled.count(kv.first))
        for (const auto& pv : kv.second) m.setEffectParam(kv.first, pv.first, pv.second);
    for (auto it = e.begin(); it != e.end(); ++it) {
      if (!enabled.count(it.key())) continue;
      const std::string w = where + ": effects." + it.key();
      for (auto p = it.value().begin(); p != it.value().end(); ++p) {
        if (p.key() == "enabled") continue;
        try {
          m.setEffectParam(it.key(), p.key(), number(p.value(), p.key(), w));
        } catch (const std::invalid_argument& ex) {
          fail(w, ex.what());
        }
      }
    }
    c.truth = m;
  }
  if (j.contains("stroke")) {
    const auto& s = j["stroke"];
    onlyKeys(s, {"enabled", "min_mm", "max_mm"}, where + ": stroke");
    if (s.contains("enabled")) c.stroke_limits = flag(s["enabled"], "enabled", where);
    if (s.contains("min_mm")) c.stroke_min_mm = number(s["min_mm"], "min_mm", where);
    if (s.contains("max_mm")) c.stroke_max_mm = number(s["max_mm"], "max_mm", where);
    if (!(c.stroke_min_mm < c.stroke_max_mm)) fail(where, "stroke min_mm must be below max_mm");
  }
  if (j.contains("sensor")) {
    const auto& s = j["sensor"];
    onlyKeys(s, {"noise", "noise_std_mm", "quantization", "quantum_mm"}, where + ": sensor");
    if (s.contains("noise")) c.sensor_noise = flag(s["noise"], "noise", where);
    if (s.contains("noise_std_mm")) c.noise_std_mm = number(s["noise_std_mm"], "noise_std_mm", where);
    if (s.contains("quantization")) c.quantization = flag(s["quantization"], "quantization", where);
    if (s.contains("quantum_mm")) c.quantum_mm = number(s["quantum_mm"], "quantum_mm", where);
    if (c.noise_std_mm < 0 || !(c.quantum_mm > 0)) fail(where, "sensor noise must be >= 0 and quantum > 0");
  }
  if (j.contains("valve")) {
    const auto& v = j["valve"];
    onlyKeys(v, {"u_min", "u_max", "pressure_max_bar"}, where + ": valve");
    if (v.contains("u_min")) c.u_min = number(v["u_min"], "u_min", where);
    if (v.contains("u_max")) c.u_max = number(v["u_max"], "u_max", where);
    if (v.contains("pressure_max_bar")) c.pressure_max_bar = number(v["pressure_max_bar"], "pressure_max_bar", where);
    if (!(c.u_min < c.u_max)) fail(where, "valve u_min must be below u_max");
  }
  if (j.contains("seed")) {
    if (!j["seed"].is_number_unsigned()) fail(where, "'seed' must be a non-negative integer");
    c.seed = j["seed"].get<std::uint64_t>();
  }
}

// The physics plant's sample time, command range, sensor and seed in the fields every kind has.
void mirrorPhysics(PlantConfig& c) {
  const auto& p = c.physics;
  c.Ts = p.Ts;
  c.u_min = p.u_min;
  c.u_max = p.u_max;
  c.stroke_limits = p.stroke_limits;
  c.stroke_min_mm = p.stroke_min_mm;
  c.stroke_max_mm = p.stroke_max_mm;
  c.sensor_noise = p.noise_std_mm > 0.0;
  c.noise_std_mm = p.noise_std_mm;
  c.quantization = p.quantum_mm > 0.0;
  c.quantum_mm = p.quantum_mm > 0.0 ? p.quantum_mm : c.quantum_mm;
  c.pressure_max_bar = p.regulator.setpoint_bar_per_V * 10.0;
  c.seed = p.seed;
}

PlantKind kindOf(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object() || !j.contains("kind")) return PlantKind::Physics;
  const auto& k = j["kind"];
  if (k == "physics") return PlantKind::Physics;
  if (k == "model") return PlantKind::Model;
  fail(where, "'kind' must be \"physics\" or \"model\"");
}
}  // namespace

const char* plantKindName(PlantKind k) noexcept {
  switch (k) {
    case PlantKind::Physics: return "physics";
    case PlantKind::Model: return "model";
    case PlantKind::External: return "external";
  }
  return "?";
}

PlantConfig PlantConfig::defaults() {
  PlantConfig c = modelDefaults();
  c.kind = PlantKind::Physics;
  c.physics = physics::PhysicsConfig::defaults();
  mirrorPhysics(c);
  return c;
}

PlantConfig PlantConfig::modelDefaults() {
  PlantConfig c;
  c.kind = PlantKind::Model;
  apply(c, nlohmann::json::parse(kDefaultJson), "built-in plant defaults");
  return c;
}

PlantConfig PlantConfig::fromJson(const nlohmann::json& j, const std::string& where) {
  if (kindOf(j, where) == PlantKind::Model) {
    PlantConfig c = modelDefaults();
    apply(c, j, where);
    return c;
  }
  PlantConfig c = defaults();
  try {
    c.physics = physics::PhysicsConfig::fromJson(j, where);
  } catch (const std::invalid_argument& e) {
    std::string what = e.what();
    // A model plant's file without its kind: say what it would take.
    if (j.is_object() && (j.contains("core") || j.contains("effects") || j.contains("sensor")) && !j.contains("kind"))
      what += " (a plant file of the model kind says \"kind\": \"model\")";
    throw std::invalid_argument(what);
  }
  mirrorPhysics(c);
  return c;
}

PlantConfig PlantConfig::fromFile(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::invalid_argument(path + ": cannot open plant config");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(f);
  } catch (const nlohmann::json::parse_error& e) {
    throw std::invalid_argument(path + ": byte " + std::to_string(e.byte) + ": not valid JSON");
  }
  return fromJson(j, path);
}

nlohmann::json PlantConfig::toJson() const {
  nlohmann::json j;
  if (kind == PlantKind::External) return {{"kind", "external"}, {"name", external.name}, {"Ts", Ts}};
  if (kind == PlantKind::Physics) {
    physics::PhysicsConfig p = physics;
    p.Ts = Ts;
    j = p.toJson();
    j["kind"] = "physics";
    return j;
  }
  j["kind"] = "model";
  j["Ts"] = Ts;
  j["output_form"] = model::outputFormName(truth.outputForm());
  const auto& p = truth.core();
  j["core"] = {{"k", p.k}, {"rho", p.rho}, {"b", p.b}, {"alpha", p.alpha}, {"beta", p.beta}, {"gamma", p.gamma}};
  nlohmann::json e = nlohmann::json::object();
  for (const auto& ce : model::catalogue()) {
    const bool on = truth.hasEffect(ce.name);
    nlohmann::json o = {{"enabled", on}};
    if (on) {
      for (int i = 0; i < truth.numEffects(); ++i) {
        if (std::string(truth.effect(i).name()) != ce.name) continue;
        const auto& ps = truth.effect(i).params();
        for (size_t q = 0; q < ps.size(); ++q) o[ps[q].name] = truth.effectParams(i)[q];
      }
    } else {
      auto eff = ce.make();
      for (const auto& ps : eff->params()) o[ps.name] = ps.def;
    }
    e[ce.name] = o;
  }
  j["effects"] = e;
  j["stroke"] = {{"enabled", stroke_limits}, {"min_mm", stroke_min_mm}, {"max_mm", stroke_max_mm}};
  j["sensor"] = {{"noise", sensor_noise},
                 {"noise_std_mm", noise_std_mm},
                 {"quantization", quantization},
                 {"quantum_mm", quantum_mm}};
  j["valve"] = {{"u_min", u_min}, {"u_max", u_max}, {"pressure_max_bar", pressure_max_bar}};
  j["seed"] = seed;
  return j;
}

Plant::Plant(const PlantConfig& cfg) : cfg_(cfg), rng_(cfg.seed) {
  if (cfg_.kind == PlantKind::Physics) {
    physics::PhysicsConfig p = cfg_.physics;
    p.Ts = cfg_.Ts;  // the sample time it is stepped at (a bus's SYNC period)
    if (!cfg_.sensor_noise) p.noise_std_mm = 0.0;
    if (!cfg_.quantization) p.quantum_mm = 0.0;
    physics_ = std::make_unique<physics::PhysicsPlant>(p);
  }
  if (cfg_.kind == PlantKind::External) {
    if (!cfg_.external.make) throw std::invalid_argument("plant of kind external without its dynamics");
    external_ = cfg_.external.make(cfg_.Ts);
  }
  reset(0.0);
}

void Plant::reset(double u0, double force_N) noexcept {
  if (physics_) {
    physics_->reset(u0, force_N);
    return;
  }
  if (external_) {
    external_->reset(validCommand(u0), force_N);
    return;
  }
  model::StepContext c;
  c.Ts = cfg_.Ts;
  c.load = force_N;
  u0 = std::clamp(u0, cfg_.u_min, cfg_.u_max);
  cfg_.truth.init(st_, u0, c);
  // Settle for a second so every effect is at rest.
  for (int i = 0; i < static_cast<int>(1.0 / cfg_.Ts); ++i) step(u0, force_N);
  rng_.seed(cfg_.seed);
}

double Plant::step(double u, double force_N) noexcept {
  if (physics_) return physics_->step(u, force_N);
  if (external_) return external_->step(validCommand(u), force_N);
  model::StepContext c;
  c.Ts = cfg_.Ts;
  c.load = force_N;
  u = validCommand(u);
  double y = cfg_.truth.step(st_, u, c);
  if (cfg_.stroke_limits) y = std::clamp(y, cfg_.stroke_min_mm, cfg_.stroke_max_mm);
  y_ = y;
  return y;
}

double Plant::validCommand(double u) const noexcept {
  if (!std::isfinite(u)) u = 0.0;  // a valve holds mid-range on a nonsense command
  return std::clamp(u, cfg_.u_min, cfg_.u_max);
}

double Plant::measure() noexcept {
  if (physics_) return physics_->measure();
  if (external_) return external_->measure();
  double y = y_;
  if (cfg_.sensor_noise && cfg_.noise_std_mm > 0) y += cfg_.noise_std_mm * noise_(rng_);
  if (cfg_.quantization) y = std::round(y / cfg_.quantum_mm) * cfg_.quantum_mm;
  return y;
}

double Plant::pressure_bar() const noexcept {
  if (physics_) return physics_->pressure_bar();
  if (external_) return external_->pressure_bar();
  const double frac = (st_.u_eff_prev - cfg_.u_min) / (cfg_.u_max - cfg_.u_min);
  return std::clamp(frac, 0.0, 1.0) * cfg_.pressure_max_bar;
}

}  // namespace pamc::plant
