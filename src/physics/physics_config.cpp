// PhysicsConfig from and to JSON. Every parameter is one entry of a table (section, key, field), so
// reading, writing and the list of known keys cannot disagree.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "io/json_fields.hpp"
#include "physics/physics_plant.hpp"

namespace pamc::physics {

namespace {

using namespace io::json_fields;

constexpr double kPi = 3.14159265358979323846;

struct Field {
  const char* key;
  double* value;
};

struct Section {
  const char* name;
  std::vector<Field> fields;
};

// The numeric sections of the file, in the order written.
std::vector<Section> sections(PhysicsConfig& c) {
  auto& g = c.regulator;
  auto& m = c.muscle;
  auto& l = c.payload;
  auto& r = c.reference;
  return {
      {"valve", {{"u_min", &c.u_min}, {"u_max", &c.u_max}}},
      {"stroke", {{"min_mm", &c.stroke_min_mm}, {"max_mm", &c.stroke_max_mm}}},
      {"sensor", {{"noise_std_mm", &c.noise_std_mm}, {"quantum_mm", &c.quantum_mm}}},
      {"regulator",
       {{"setpoint_offset_V", &g.setpoint_offset_V},
        {"setpoint_bar_per_V", &g.setpoint_bar_per_V},
        {"supply_bar", &g.supply_bar},
        {"atmosphere_bar", &g.atmosphere_bar},
        {"conductance_dm3_per_s_bar", &g.conductance_dm3_per_s_bar},
        {"critical_ratio", &g.critical_ratio},
        {"laminar_ratio", &g.laminar_ratio},
        {"band_bar", &g.band_bar},
        {"tau_s", &g.tau_s},
        {"polytropic_index", &g.polytropic_index},
        {"temperature_K", &g.temperature_K},
        {"dead_volume_cm3", &g.dead_volume_cm3}}},
      {"muscle",
       {{"diameter_mm", &m.diameter_mm},
        {"length_mm", &m.length_mm},
        {"braid_angle_deg", &m.braid_angle_deg},
        {"tondu_k", &m.tondu_k},
        {"rubber_N_per_mm", &m.rubber_N_per_mm},
        {"hysteresis_N", &m.hysteresis_N},
        {"hysteresis_N_per_bar", &m.hysteresis_N_per_bar},
        {"hysteresis_travel_mm", &m.hysteresis_travel_mm}}},
      {"payload",
       {{"mass_kg", &l.mass_kg},
        {"gravity_m_per_s2", &l.gravity_m_per_s2},
        {"spring_preload_N", &l.spring_preload_N},
        {"spring_N_per_mm", &l.spring_N_per_mm},
        {"viscous_N_s_per_m", &l.viscous_N_s_per_m},
        {"coulomb_N", &l.coulomb_N},
        {"coulomb_velocity_mm_per_s", &l.coulomb_velocity_mm_per_s}}},
      {"reference",
       {{"k", &r.k},
        {"rho", &r.rho},
        {"b", &r.b},
        {"alpha", &r.alpha},
        {"beta", &r.beta},
        {"gamma", &r.gamma},
        {"tau_valve_s", &r.tau_valve_s}}},
  };
}

struct EffectEntry {
  const char* name;
  bool* enabled;
  std::vector<Field> params;
  bool in_rig;  // switchable in mode rig (the others are part of the rig's physics)
};

// The catalogue's effects, in its order (src/model/effects/catalogue.inc), with its parameter names.
std::vector<EffectEntry> effectTable(Effects& e) {
  return {
      {"pressure_lag", &e.pressure_lag.enabled, {{"tau", &e.pressure_lag.tau}, {"slew", &e.pressure_lag.slew}}, false},
      {"asymmetry",
       &e.asymmetry.enabled,
       {{"gain", &e.asymmetry.gain}, {"w_up", &e.asymmetry.w_up}, {"w_down", &e.asymmetry.w_down}},
       false},
      {"creep", &e.creep.enabled, {{"fraction", &e.creep.fraction}, {"tau", &e.creep.tau}}, true},
      {"mass_spring", &e.mass_spring.enabled, {{"fn", &e.mass_spring.fn}, {"zeta", &e.mass_spring.zeta}}, false},
      {"force_loop",
       &e.force_loop.enabled,
       {{"fn", &e.force_loop.fn},
        {"zeta", &e.force_loop.zeta},
        {"zmax", &e.force_loop.zmax},
        {"delta", &e.force_loop.delta}},
       false},
      {"friction_hysteresis",
       &e.friction_hysteresis.enabled,
       {{"zmax", &e.friction_hysteresis.zmax}, {"delta", &e.friction_hysteresis.delta}},
       false},
      {"delay", &e.delay.enabled, {{"d", &e.delay.d}}, true},
      {"dead_band", &e.dead_band.enabled, {{"threshold", &e.dead_band.threshold}}, true},
      {"load", &e.load.enabled, {{"compliance", &e.load.compliance}}, false},
      {"saturation", &e.saturation.enabled, {{"knee", &e.saturation.knee}, {"width", &e.saturation.width}}, false},
      {"warm_up",
       &e.warm_up.enabled,
       {{"tau", &e.warm_up.tau}, {"gain", &e.warm_up.gain}, {"shift", &e.warm_up.shift}},
       true},
  };
}

const char* modeName(Mode m) { return m == Mode::Rig ? "rig" : "reference"; }

void positive(double v, const std::string& key, const std::string& where) {
  if (!(v > 0.0)) fail(where, "'" + key + "' must be positive");
}

void validate(const PhysicsConfig& c, const std::string& where) {
  positive(c.Ts, "Ts", where);
  if (c.Ts > 1.0) fail(where, "'Ts' must be at most 1 s");
  if (!(c.u_min < c.u_max)) fail(where, "valve: u_min must be below u_max");
  if (!(c.stroke_min_mm < c.stroke_max_mm)) fail(where, "stroke: min_mm must be below max_mm");
  if (c.noise_std_mm < 0.0) fail(where, "sensor: 'noise_std_mm' must be >= 0");
  if (c.quantum_mm < 0.0) fail(where, "sensor: 'quantum_mm' must be >= 0 (0: no quantisation)");
  const auto& g = c.regulator;
  const std::string wg = where + ": regulator";
  positive(g.setpoint_bar_per_V, "setpoint_bar_per_V", wg);
  positive(g.supply_bar, "supply_bar", wg);
  positive(g.atmosphere_bar, "atmosphere_bar", wg);
  positive(g.conductance_dm3_per_s_bar, "conductance_dm3_per_s_bar", wg);
  if (!(g.critical_ratio >= 0.0 && g.critical_ratio < g.laminar_ratio && g.laminar_ratio < 1.0))
    fail(wg, "need 0 <= 'critical_ratio' < 'laminar_ratio' < 1");
  positive(g.band_bar, "band_bar", wg);
  positive(g.tau_s, "tau_s", wg);
  if (!(g.polytropic_index >= 1.0 && g.polytropic_index <= 1.4)) fail(wg, "'polytropic_index' must be in [1, 1.4]");
  positive(g.temperature_K, "temperature_K", wg);
  if (g.dead_volume_cm3 < 0.0) fail(wg, "'dead_volume_cm3' must be >= 0");
  const auto& m = c.muscle;
  const std::string wm = where + ": muscle";
  positive(m.diameter_mm, "diameter_mm", wm);
  positive(m.length_mm, "length_mm", wm);
  if (!(m.braid_angle_deg > 1.0 && m.braid_angle_deg < 54.0))
    fail(wm, "'braid_angle_deg' must be between 1 and 54 (the muscle contracts below 54.7 degrees)");
  positive(m.tondu_k, "tondu_k", wm);
  if (m.rubber_N_per_mm < 0.0 || m.hysteresis_N < 0.0 || m.hysteresis_N_per_bar < 0.0)
    fail(wm, "'rubber_N_per_mm', 'hysteresis_N' and 'hysteresis_N_per_bar' must be >= 0");
  positive(m.hysteresis_travel_mm, "hysteresis_travel_mm", wm);
  const auto& l = c.payload;
  const std::string wl = where + ": payload";
  positive(l.mass_kg, "mass_kg", wl);
  if (l.viscous_N_s_per_m < 0.0 || l.coulomb_N < 0.0) fail(wl, "'viscous_N_s_per_m' and 'coulomb_N' must be >= 0");
  positive(l.coulomb_velocity_mm_per_s, "coulomb_velocity_mm_per_s", wl);
  const auto& r = c.reference;
  const std::string wr = where + ": reference";
  positive(r.tau_valve_s, "tau_valve_s", wr);
  const auto& e = c.effects;
  const std::string we = where + ": effects";
  positive(e.pressure_lag.tau, "pressure_lag.tau", we);
  positive(e.pressure_lag.slew, "pressure_lag.slew", we);
  positive(e.asymmetry.w_up, "asymmetry.w_up", we);
  positive(e.asymmetry.w_down, "asymmetry.w_down", we);
  positive(e.creep.tau, "creep.tau", we);
  positive(e.mass_spring.fn, "mass_spring.fn", we);
  if (e.mass_spring.zeta < 0.0) fail(we, "'mass_spring.zeta' must be >= 0");
  positive(e.force_loop.fn, "force_loop.fn", we);
  if (e.force_loop.zeta < 0.0 || e.force_loop.zmax < 0.0)
    fail(we, "'force_loop.zeta' and 'force_loop.zmax' must be >= 0");
  positive(e.force_loop.delta, "force_loop.delta", we);
  if (e.friction_hysteresis.zmax < 0.0) fail(we, "'friction_hysteresis.zmax' must be >= 0");
  positive(e.friction_hysteresis.delta, "friction_hysteresis.delta", we);
  if (e.delay.d < 0.0 || e.delay.d > (kDelayRing - 2) * c.Ts)
    fail(we, "'delay.d' must be between 0 and " + std::to_string((kDelayRing - 2) * c.Ts) + " s");
  positive(e.saturation.width, "saturation.width", we);
  positive(e.warm_up.tau, "warm_up.tau", we);
  if (e.mass_spring.enabled && e.force_loop.enabled)
    fail(we, "mass_spring and force_loop are alternatives (the same payload); enable one");
  if (c.mode == Mode::Reference) {
    // The uniform substep (reference_substeps / 4 per sample) must resolve the slow dynamics: the
    // payload's fastest mode (force_loop's pre-sliding stiffness included) and pressure_lag.
    if (c.reference_substeps < 4) fail(where, "'reference_substeps' must be at least 4");
    const double h = c.Ts / (c.reference_substeps / 4);
    if (e.pressure_lag.enabled && h > 0.5 * e.pressure_lag.tau)
      fail(we, "'pressure_lag.tau' is too short for 'reference_substeps'");
    double w = 0.0;
    if (e.mass_spring.enabled) w = 2.0 * kPi * e.mass_spring.fn;
    if (e.force_loop.enabled) w = 2.0 * kPi * e.force_loop.fn * std::sqrt(1.0 + e.force_loop.zmax / e.force_loop.delta);
    if (w * h > 0.5) fail(we, "the payload's natural frequency is too high for 'reference_substeps'");
  }
  if (c.mode == Mode::Rig) {
    Effects copy = c.effects;
    for (const auto& x : effectTable(copy))
      if (*x.enabled && !x.in_rig)
        fail(we + "." + x.name,
             "not switchable in mode 'rig' (its physics is part of the rig); there: creep, delay, "
             "dead_band, warm_up");
  }
}

void apply(PhysicsConfig& c, const nlohmann::json& j, const std::string& where) {
  std::vector<std::string> top = {"kind", "mode", "Ts", "substeps", "reference_substeps", "seed", "effects"};
  auto secs = sections(c);
  for (const auto& s : secs) top.emplace_back(s.name);
  onlyKeys(j, top, where);
  if (j.contains("mode")) {
    const auto& m = j["mode"];
    if (!m.is_string() || (m.get<std::string>() != "rig" && m.get<std::string>() != "reference"))
      fail(where, "'mode' must be \"rig\" or \"reference\"");
    c.mode = m.get<std::string>() == "rig" ? Mode::Rig : Mode::Reference;
  }
  if (j.contains("Ts")) c.Ts = number(j["Ts"], "Ts", where);
  if (j.contains("substeps")) c.substeps = count(j["substeps"], "substeps", where);
  if (j.contains("reference_substeps"))
    c.reference_substeps = count(j["reference_substeps"], "reference_substeps", where);
  if (j.contains("seed")) {
    const auto& sd = j["seed"];
    if (!sd.is_number_integer() || (!sd.is_number_unsigned() && sd.get<long long>() < 0))
      fail(where, "'seed' must be a non-negative integer");
    c.seed = j["seed"].get<std::uint64_t>();
  }
  for (const auto& s : secs) {
    if (!j.contains(s.name)) continue;
    const auto& o = j[s.name];
    const std::string w = where + ": " + s.name;
    std::vector<std::string> keys;
    for (const auto& f : s.fields) keys.emplace_back(f.key);
    if (std::string(s.name) == "stroke") keys.emplace_back("enabled");
    onlyKeys(o, keys, w);
    for (const auto& f : s.fields)
      if (o.contains(f.key)) *f.value = number(o[f.key], f.key, w);
    if (std::string(s.name) == "stroke" && o.contains("enabled")) c.stroke_limits = flag(o["enabled"], "enabled", w);
  }
  if (j.contains("effects")) {
    const auto& e = j["effects"];
    const std::string we = where + ": effects";
    auto table = effectTable(c.effects);
    std::vector<std::string> names;
    for (const auto& x : table) names.emplace_back(x.name);
    onlyKeys(e, names, we);
    for (const auto& x : table) {
      if (!e.contains(x.name)) continue;
      const auto& o = e[x.name];
      const std::string w = we + "." + x.name;
      std::vector<std::string> keys = {"enabled"};
      for (const auto& p : x.params) keys.emplace_back(p.key);
      onlyKeys(o, keys, w);
      // Listing an effect switches it on unless it says otherwise (as in the emulator's files).
      *x.enabled = o.contains("enabled") ? flag(o["enabled"], "enabled", w) : true;
      for (const auto& p : x.params)
        if (o.contains(p.key)) *p.value = number(o[p.key], p.key, w);
    }
  }
  validate(c, where);
}

}  // namespace

PhysicsConfig PhysicsConfig::defaults() { return PhysicsConfig{}; }

PhysicsConfig PhysicsConfig::fromJson(const nlohmann::json& j, const std::string& where) {
  PhysicsConfig c = defaults();
  apply(c, j, where);
  return c;
}

nlohmann::json PhysicsConfig::toJson() const {
  PhysicsConfig c = *this;  // the tables point into a copy
  nlohmann::json j;
  j["kind"] = "physics";
  j["mode"] = modeName(c.mode);
  j["Ts"] = c.Ts;
  j["substeps"] = c.substeps;
  j["reference_substeps"] = c.reference_substeps;
  j["seed"] = c.seed;
  for (const auto& s : sections(c)) {
    nlohmann::json o = nlohmann::json::object();
    for (const auto& f : s.fields) o[f.key] = *f.value;
    if (std::string(s.name) == "stroke") o["enabled"] = c.stroke_limits;
    j[s.name] = o;
  }
  nlohmann::json e = nlohmann::json::object();
  for (const auto& x : effectTable(c.effects)) {
    nlohmann::json o = {{"enabled", *x.enabled}};
    for (const auto& p : x.params) o[p.key] = *p.value;
    e[x.name] = o;
  }
  j["effects"] = e;
  return j;
}

}  // namespace pamc::physics
