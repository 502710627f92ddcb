#include "io/model_file.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

#include "io/measurement.hpp"

namespace pamc::io {

namespace {

// Names from the file (keys, effect names) may hold control characters; an error stays one line.
std::string printable(const std::string& s) {
  std::string out;
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '\n')
      out += "\\n";
    else if (c == '\r')
      out += "\\r";
    else if (c == '\t')
      out += "\\t";
    else if (u < 0x20 || u == 0x7F) {
      static constexpr char kHex[] = "0123456789abcdef";
      out += "\\x";
      out += kHex[u >> 4];
      out += kHex[u & 0x0F];
    } else {
      out += c;
    }
  }
  return out;
}

}  // namespace

nlohmann::json modelToJson(const model::Model& m) {
  nlohmann::json j;
  j["format"] = "pamc-model/1";
  const auto& p = m.core();
  j["core"] = {{"k", p.k}, {"rho", p.rho}, {"b", p.b}, {"alpha", p.alpha}, {"beta", p.beta}, {"gamma", p.gamma}};
  j["output_form"] = model::outputFormName(m.outputForm());
  nlohmann::json e = nlohmann::json::array();
  for (int i = 0; i < m.numEffects(); ++i) {
    nlohmann::json ps = nlohmann::json::object();
    const auto& spec = m.effect(i).params();
    for (size_t q = 0; q < spec.size(); ++q) ps[spec[q].name] = m.effectParams(i)[q];
    e.push_back({{"name", m.effect(i).name()}, {"params", ps}});
  }
  j["effects"] = e;
  const auto& r = m.range();
  if (r.known)
    j["range"] = {{"input", {r.input.lo, r.input.hi}},
                  {"output", {r.output.lo, r.output.hi}},
                  {"input_rate", {r.rate.lo, r.rate.hi}}};
  return j;
}

namespace {

// "range": {"input": [lo, hi], "output": [lo, hi], "input_rate": [lo, hi]} (all three, lo <= hi).
model::OperatingRange rangeFromJson(const nlohmann::json& j, const std::string& where) {
  auto fail = [&](const std::string& what) { throw InputError(where + ": range: " + what); };
  if (!j.is_object()) fail("must be an object with 'input', 'output' and 'input_rate'");
  model::OperatingRange r;
  const std::pair<const char*, model::Interval*> keys[] = {
      {"input", &r.input}, {"output", &r.output}, {"input_rate", &r.rate}};
  for (const auto& [key, dst] : keys) {
    if (!j.contains(key)) fail(std::string("missing '") + key + "'");
    const auto& v = j[key];
    if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number())
      fail(std::string("'") + key + "' must be [low, high]");
    dst->lo = v[0].get<double>();
    dst->hi = v[1].get<double>();
    if (!std::isfinite(dst->lo) || !std::isfinite(dst->hi) || dst->lo > dst->hi)
      fail(std::string("'") + key + "' must be finite with low <= high");
  }
  for (auto it = j.begin(); it != j.end(); ++it)
    if (it.key() != "input" && it.key() != "output" && it.key() != "input_rate")
      fail("unknown key '" + printable(it.key()) + "'");
  r.known = true;
  return r;
}

}  // namespace

model::Model modelFromJson(const nlohmann::json& j, const std::string& where) {
  auto fail = [&](const std::string& what) -> void { throw InputError(where + ": " + printable(what)); };
  auto num = [&](const nlohmann::json& v, const std::string& key) {
    if (!v.is_number()) fail("'" + key + "' must be a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail("'" + key + "' must be finite");
    return d;
  };
  if (!j.is_object()) fail("a model file must be a JSON object");
  if (!j.contains("format") || j["format"] != "pamc-model/1") fail("'format' must be \"pamc-model/1\"");
  if (!j.contains("core") || !j["core"].is_object()) fail("missing object 'core'");
  const auto& c = j["core"];
  model::BoucWenParams p;
  const char* names[] = {"k", "rho", "b", "alpha", "beta", "gamma"};
  double* dst[] = {&p.k, &p.rho, &p.b, &p.alpha, &p.beta, &p.gamma};
  for (int i = 0; i < 6; ++i) {
    if (!c.contains(names[i])) fail(std::string("core: missing '") + names[i] + "'");
    *dst[i] = num(c[names[i]], std::string("core.") + names[i]);
  }
  for (auto it = c.begin(); it != c.end(); ++it) {
    bool known = false;
    for (auto* n : names) known = known || it.key() == n;
    if (!known) fail("core: unknown parameter '" + it.key() + "'");
  }
  model::Model m(p);
  // A file from before the field was fitted in eq. (6)'s printed form, and is run in it.
  model::OutputForm form = model::OutputForm::Printed;
  if (j.contains("output_form")) {
    if (!j["output_form"].is_string() || !model::parseOutputForm(j["output_form"].get<std::string>(), form))
      fail("'output_form' must be \"aligned\" or \"printed\"");
  }
  m.setOutputForm(form);
  // Files from before ranges were recorded have none: the model then holds everywhere it is used.
  if (j.contains("range")) m.setRange(rangeFromJson(j["range"], where));
  if (j.contains("effects")) {
    if (!j["effects"].is_array()) fail("'effects' must be an array");
    for (const auto& e : j["effects"]) {
      if (!e.is_object() || !e.contains("name") || !e["name"].is_string()) fail("each effect needs a 'name'");
      const std::string name = e["name"];
      try {
        m.addEffect(name);
        if (e.contains("params")) {
          if (!e["params"].is_object()) fail("effect " + name + ": 'params' must be an object");
          for (auto it = e["params"].begin(); it != e["params"].end(); ++it)
            m.setEffectParam(name, it.key(), num(it.value(), name + "." + it.key()));
        }
      } catch (const std::invalid_argument& ex) {
        fail(ex.what());
      }
    }
  }
  return m;
}

nlohmann::json readJsonFile(const std::string& path, const std::string& what) {
  std::ifstream f(path);
  if (!f) throw InputError(path + ": cannot open " + what);
  try {
    return nlohmann::json::parse(f);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(path + ": byte " + std::to_string(e.byte) + ": not valid JSON");
  } catch (const nlohmann::json::exception& e) {
    // The parser reports a number it cannot hold ("1e999") as out_of_range, not parse_error.
    const std::string text = e.what();
    const auto tag = text.find("] ");
    throw InputError(path + ": not valid JSON: " + (tag == std::string::npos ? text : text.substr(tag + 2)));
  }
}

model::Model readModelFile(const std::string& path) { return modelFromJson(readJsonFile(path, "model file"), path); }

void writeModelFile(const std::string& path, const model::Model& m, const nlohmann::json& fit) {
  nlohmann::json j = modelToJson(m);
  if (!fit.is_null()) j["fit"] = fit;
  writeFileAtomic(path, j.dump(2) + "\n");
}

}  // namespace pamc::io
