// Self-contained HTML report: inline SVG only, no scripts, no external resources. How to read it:
// docs/diagnosis.md, "Reading the report".
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "core/atomic_file.hpp"
#include "diagnosis/diagnose.hpp"

namespace lw::diagnosis {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::string Esc(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string Num(double v, int digits = 2) {
  if (!std::isfinite(v)) return "-";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  if (b[0] == '-' && std::string(b + 1).find_first_not_of("0.") == std::string::npos) return b + 1;  // no "-0.0"
  return b;
}

// Significant digits for parameter values of any magnitude.
std::string Sig(double v) {
  if (!std::isfinite(v)) return "-";
  const double a = std::fabs(v);
  return Num(v, a >= 100 ? 0 : a >= 10 ? 1 : a >= 1 ? 2 : a >= 0.1 ? 3 : 4);
}

std::string Date(core::TimePoint t) {
  return core::FormatIsoTime(t).substr(0, 10);
}

std::string Hex(double r, double g, double b) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", static_cast<int>(std::clamp(r, 0.0, 255.0)),
                static_cast<int>(std::clamp(g, 0.0, 255.0)), static_cast<int>(std::clamp(b, 0.0, 255.0)));
  return buf;
}

// Piecewise-linear colour ramp through `n` stops (RGB) for v in [0, 1].
std::string Ramp(const double (*stops)[3], int n, double v) {
  v = std::clamp(std::isfinite(v) ? v : 0.0, 0.0, 1.0) * (n - 1);
  const int k = std::min(n - 2, static_cast<int>(v));
  const double f = v - k;
  return Hex(stops[k][0] + f * (stops[k + 1][0] - stops[k][0]), stops[k][1] + f * (stops[k + 1][1] - stops[k][1]),
             stops[k][2] + f * (stops[k + 1][2] - stops[k][2]));
}

// Diverging blue - white - red (ColorBrewer RdBu) for v in [-1, 1]: red = positive.
std::string Diverging(double v) {
  static const double kStops[5][3] = {{33, 102, 172}, {103, 169, 207}, {247, 247, 247}, {239, 138, 98}, {178, 24, 43}};
  return Ramp(kStops, 5, 0.5 * (std::clamp(v, -1.0, 1.0) + 1.0));
}

// Sequential pale yellow - dark red (ColorBrewer YlOrRd) for v in [0, 1]: dark = high.
std::string Sequential(double v) {
  static const double kStops[5][3] = {{255, 255, 204}, {254, 217, 118}, {253, 141, 60}, {227, 26, 28}, {128, 0, 38}};
  return Ramp(kStops, 5, v);
}

// A "nice" round number >= v (1, 2, 2.5, 5 x 10^k).
double NiceCeil(double v) {
  if (!(v > 0)) return 1;
  const double p = std::pow(10.0, std::floor(std::log10(v)));
  for (double m : {1.0, 2.0, 2.5, 5.0, 10.0})
    if (m * p >= v * (1 - 1e-9)) return m * p;
  return 10 * p;
}

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

// ---------------------------------------------------------------------------------------------------
// Parameters: names, units and meaning (docs/diagnosis.md, section 5).

struct ParamInfo {
  const char* key;
  const char* name;
  const char* unit;
  const char* meaning;
};

constexpr ParamInfo kParams[] = {
    {"h", "h (hardening)", "fraction",
     "Wear-rate reduction where normal stress (impact) is at its robust maximum, once hardening has saturated: "
     "0.3 = 30 % slower."},
    {"tau_days", "&tau; (hardening time constant)", "days", "The reduction builds up as 1 - exp(-t / &tau;) from installation."},
    {"saturation_days", "saturation time", "days", "3 &tau;: about 95 % of the hardening is reached by then."},
    {"weighted_by", "weighted by", "", "The map field that says where hardening acts."},
    {"g", "g (softer core)", "fraction", "Wear-rate increase once the surface has worn to mid-thickness: 0.3 = 30 % faster."},
    {"onset_depth_mm", "d0 (onset depth)", "mm of worn depth", "Worn depth at which the wear starts to accelerate."},
    {"full_depth_mm", "full depth", "mm of worn depth", "Worn depth at which the full increase g is reached."},
    {"beta", "&beta; (squeeze wear)", "map-intensity units",
     "Extra wear per unit of normal stress next to the DEM's impact/abrasion wear: rate = k (I + &beta; n)."},
    {"form", "form", "", "shift: the DEM's wear profile slides along the liner; tilt: top vs bottom rates drift linearly."},
    {"p_per_100_days", "p (tilt rate)", "per 100 days",
     "Change of the top-versus-bottom wear-rate ratio per 100 days: 0.1 = the top wears 10 % faster relative to "
     "the bottom after 100 days."},
    {"top_vs_bottom_change_over_campaign", "tilt over the campaign", "fraction",
     "Top-versus-bottom wear-rate change reached by the end of the campaign."},
    {"shift_per_100_days", "v (profile shift rate)", "concave heights per 100 days",
     "How fast the DEM's wear profile moves along the liner (+ = upwards)."},
    {"shift_over_campaign_m", "shift over the campaign", "m", "Distance the wear profile moved by the end of the campaign."},
    {"amplitude", "A (circumferential amplitude)", "fraction",
     "Wear varies around the liner as 1 + A cos(&theta; - &theta;f): 0.2 = 20 % more on one side, 20 % less opposite."},
    {"theta_f_deg", "&theta;f (most-worn side)", "deg", "Angle of the side that wears most (coarser feed there)."},
    {"phi", "&phi; (tonnage dependence)", "fraction",
     "Share of the wear rate that follows the throughput log instead of calendar time: 1 = fully."},
    {"throughput_variation_cv", "throughput variation", "fraction",
     "Coefficient of variation of the throughput (x abrasiveness) over the campaign."},
    {"sensor_id", "sensor", "", "The sensor that saw the step."},
    {"time", "time", "UTC", "When the material broke out."},
    {"depth_mm", "depth lost", "mm",
     "Depth of material lost at once (a sensor's step: the later readings are offset by it; else the crater's median "
     "depth below the wear around it in the scan)."},
    {"z_m", "z", "m", "Height of that sensor on the liner, or of the crater's centre."},
    {"theta_deg", "&theta;", "deg", "Angle of that sensor around the liner, or of the crater's centre."},
    {"z_min_m", "z from", "m", "Lowest face of the crater in the scan."},
    {"z_max_m", "z to", "m", "Highest face of the crater in the scan."},
    {"theta_min_deg", "&theta; from", "deg", "The crater's extent around the liner: from this angle..."},
    {"theta_max_deg", "&theta; to", "deg", "...to this one (counter-clockwise)."},
    {"area_m2", "area", "m^2", "Area of the scan's faces in the crater."},
};

// What the "improved" model is in this report's words (DiagnosisResult::improved_model).
std::string ImprovedWords(const DiagnosisResult& r) {
  return ImprovedModelLabel(r.improved_model);
}

// The right-hand map's title, short enough for the map's width.
std::string AfterTitle(const DiagnosisResult& r) {
  return r.improved_model == ImprovedModel::kFindings        ? ImprovedWords(r)
         : r.improved_model == ImprovedModel::kRefitBaseline ? std::string("refit only (no findings)")
                                                             : std::string("= baseline (refit failed)");
}

// What the residual maps' right-hand ("AFTER") map is, for their captions.
std::string AfterWords(const DiagnosisResult& r) {
  switch (r.improved_model) {
    case ImprovedModel::kFindings:
      return "right: the model with the findings";
    case ImprovedModel::kRefitBaseline:
      return "right: <b>a refit only, no findings</b>: its faces are Eq. 9's, the same as on the left; only the sensors "
             "differ, each with the map-error term the refit fitted to its own readings (so they are expected to look "
             "better: that is not a finding)";
    case ImprovedModel::kBaseline:
      break;
  }
  return "right: the same baseline (the refit failed)";
}

// Used sensors with a residual, largest |residual| first.
std::vector<const SensorNoise*> ByResidual(const DiagnosisResult& r) {
  std::vector<const SensorNoise*> v;
  for (const SensorNoise& n : r.sensors)
    if (n.used && std::isfinite(n.residual_mm) && std::isfinite(n.noise_sd_mm)) v.push_back(&n);
  std::stable_sort(v.begin(), v.end(), [](const SensorNoise* a, const SensorNoise* b) {
    return std::fabs(a->residual_mm) > std::fabs(b->residual_mm);
  });
  return v;
}

std::string Signed(double v, int digits = 1) {
  return (v > 0 ? "+" : "") + Num(v, digits);
}

const ParamInfo* FindParam(const std::string& key) {
  for (const ParamInfo& p : kParams)
    if (key == p.key) return &p;
  return nullptr;
}

// The key of the value a "*_stderr" key belongs to ("p_stderr" -> "p_per_100_days").
std::string StderrOwner(const nlohmann::ordered_json& params, const std::string& key) {
  const std::string base = key.substr(0, key.size() - 7);
  if (params.contains(base)) return base;
  for (auto it = params.begin(); it != params.end(); ++it)
    if (it.key().rfind(base + "_", 0) == 0 && it.key().find("_stderr") == std::string::npos) return it.key();
  return "";
}

std::string JsonValue(const nlohmann::ordered_json& v) {
  if (v.is_number()) return Sig(v.get<double>());
  if (v.is_string()) return Esc(v.get<std::string>());
  return Esc(v.dump());
}

std::string ParameterTable(const nlohmann::ordered_json& params) {
  if (!params.is_object() || params.empty()) return "";
  std::ostringstream s;
  s << "<table class='params'><tr><th>parameter</th><th>value</th><th>unit</th><th>uncertainty (1 sd)</th>"
       "<th>meaning</th></tr>";
  for (auto it = params.begin(); it != params.end(); ++it) {
    const std::string& key = it.key();
    if (key.size() > 7 && key.compare(key.size() - 7, 7, "_stderr") == 0 && !StderrOwner(params, key).empty()) continue;
    std::string se = "-";
    for (auto jt = params.begin(); jt != params.end(); ++jt) {
      const std::string& k2 = jt.key();
      if (k2.size() > 7 && k2.compare(k2.size() - 7, 7, "_stderr") == 0 && StderrOwner(params, k2) == key &&
          jt.value().is_number())
        se = "&plusmn; " + Sig(jt.value().get<double>());
    }
    const ParamInfo* info = FindParam(key);
    const bool same = info && key == info->name;
    s << "<tr><td>" << (info ? info->name : "") << (same ? "" : " <code>" + Esc(key) + "</code>") << "</td><td class='num'>"
      << JsonValue(it.value()) << "</td><td>" << (info ? info->unit : "") << "</td><td class='num'>" << se << "</td><td>"
      << (info ? info->meaning : "") << "</td></tr>";
  }
  s << "</table>";
  return s.str();
}

// A hypothesis' fitted parameters in physical terms (the JSON holds the fit's own variables).
std::string HypothesisParams(const nlohmann::ordered_json& p, double thickness_new_mm) {
  if (!p.is_object()) return "";
  std::ostringstream s;
  auto get = [&](const char* k) { return p.contains(k) && p[k].is_number() ? p[k].get<double>() : std::nan(""); };
  std::string sep;
  auto add = [&](const std::string& text) {
    s << sep << text;
    sep = "; ";
  };
  if (p.contains("h")) add("h = " + Sig(get("h")));
  if (p.contains("log_tau")) add("&tau; = " + Sig(std::exp(get("log_tau"))) + " days");
  if (p.contains("g")) add("g = " + Sig(get("g")));
  if (p.contains("d0")) add("d0 = " + Num(get("d0") * 0.5 * thickness_new_mm, 1) + " mm");
  if (p.contains("d0") && p.contains("w")) {
    const double half = 0.5 * thickness_new_mm, onset = get("d0") * half;
    add("full by " + Num(onset + std::max(get("w") * (half - onset), 1.0), 1) + " mm");
  }
  if (p.contains("beta")) add("&beta; = " + Sig(get("beta")));
  if (p.contains("p")) add("p = " + Sig(get("p")) + " per 100 days");
  if (p.contains("v")) add("v = " + Sig(get("v")) + " heights per 100 days");
  if (p.contains("a") && p.contains("b")) {
    double th = std::atan2(get("b"), get("a")) * 180.0 / kPi;
    if (th < 0) th += 360.0;
    add("A = " + Sig(std::hypot(get("a"), get("b"))) + ", &theta;f = " + Num(th, 0) + " deg");
  }
  if (p.contains("phi")) add("&phi; = " + Sig(get("phi")));
  return s.str();
}

// Per effect not named, the smallest strength these data would have shown (the JSON's `limits`).
std::string LimitsSection(const DiagnosisResult& r) {
  std::ostringstream h;
  h << "<h2 id='limits'>What these data could not show</h2>";
  bool any = false;
  for (const DetectionLimit& l : r.limits)
    if (!l.named) {
      if (!any) h << "<ul>";
      any = true;
      h << "<li>" << Esc(l.sentence) << ". To see a smaller one: " << Esc(l.would_show_with) << ".</li>";
    }
  h << (any ? "</ul>" : "<p>Every tested effect was named, or no effect could be tested.</p>");
  h << "<p class='caption'>From each effect's fit: the standard error of its strength at this data's noise; an effect "
       "this strong is named about 84 % of the time, one at the limit minus one standard error about half.</p>";
  return h.str();
}

std::string EffectWords(const std::string& effect) {
  if (effect == kWorkHardening) return "work hardening: the liner hardened under impact and wore slower over time";
  if (effect == kHardnessGradient) return "hardness gradient: a softer core, wear accelerated with worn depth";
  if (effect == kSqueezeWear) return "squeeze wear: extra wear where normal stress is high";
  if (effect == kProfileEvolution) return "profile evolution: the wear pattern moved along the liner as it wore";
  if (effect == kFeedSegregation) return "feed segregation: one side of the liner wears more";
  if (effect == kThroughputVariation) return "throughput variation: wear followed the tonnage, not the calendar";
  if (effect == kMaterialLoss) return "material loss: a piece broke out of the liner (seen by a sensor or in a scan)";
  if (effect == kUnexplained) return "unexplained: the mismatch is real but no modelled effect explains it";
  return effect;
}

std::string ModelWords(const std::string& model) {
  std::string out, part;
  std::istringstream in(model);
  while (std::getline(in, part, '+')) {
    if (!out.empty()) out += " + ";
    const size_t colon = part.find(':');
    std::string name = part.substr(0, colon);
    std::replace(name.begin(), name.end(), '_', ' ');
    out += name;
    if (colon != std::string::npos) out += " (" + part.substr(colon + 1) + ")";
  }
  return out;
}

// ---------------------------------------------------------------------------------------------------
// The unwrapped liner.

struct MapFrame {
  double theta_lo = 0, theta_hi = 360, z_lo = 0, z_hi = 1;
  double w = 500, h = 240;                    // plot area, px
  double ml = 46, mr = 10, mt = 22, mb = 34;  // margins
  double X(double theta) const { return ml + w * (theta - theta_lo) / (theta_hi - theta_lo); }
  double Y(double z) const { return mt + h * (z_hi - z) / (z_hi - z_lo); }
  double Width() const { return ml + w + mr; }
  double Height() const { return mt + h + mb; }
};

MapFrame FrameOf(const LinerReport& L) {
  MapFrame f;
  double tlo = 1e300, thi = -1e300, zlo = 1e300, zhi = -1e300;
  for (const LinerTile& t : L.tiles)
    for (int k = 0; k < t.corners; ++k) {
      tlo = std::min(tlo, t.theta_deg[k]);
      thi = std::max(thi, t.theta_deg[k]);
      zlo = std::min(zlo, t.z_m[k]);
      zhi = std::max(zhi, t.z_m[k]);
    }
  if (zlo < zhi) {
    f.z_lo = zlo;
    f.z_hi = zhi;
  }
  if (tlo < thi && thi - tlo < 300) {  // a sector map: its own angular range
    f.theta_lo = std::floor(tlo / 10) * 10;
    f.theta_hi = std::ceil(thi / 10) * 10;
  }
  return f;
}

struct Marker {
  std::string id;
  double theta = 0, z = 0;
  std::string fill = "#fff";
  std::string title;
  std::string value;  ///< shown after the id (sensor residuals when there is no scan)
};

// `ids` numbers the clip paths of one document (unique ids).
std::string LinerMap(int& ids, const LinerReport& L, const MapFrame& f, const std::vector<double>& values,
                     const std::function<std::string(double)>& colour, const std::string& title, const std::string& unit,
                     const std::vector<Marker>& markers, const std::vector<const Region*>& regions,
                     const ThinnestPoint* thinnest) {
  std::ostringstream s;
  const int clip = ++ids;
  s << "<svg xmlns='http://www.w3.org/2000/svg' class='map' width='" << Num(f.Width(), 0) << "' height='" << Num(f.Height(), 0)
    << "'><defs><clipPath id='clip" << clip << "'><rect x='" << f.ml << "' y='" << f.mt << "' width='" << f.w << "' height='"
    << f.h << "'/></clipPath></defs>";
  s << "<text x='" << f.ml << "' y='14' font-size='12' font-weight='bold'>" << Esc(title) << "</text>";
  s << "<rect x='" << f.ml << "' y='" << f.mt << "' width='" << f.w << "' height='" << f.h << "' fill='#e0e0e0'/>";
  s << "<g clip-path='url(#clip" << clip << ")' stroke-width='0.6' stroke-linejoin='round'>";
  for (size_t i = 0; i < L.tiles.size() && i < values.size(); ++i) {
    const LinerTile& t = L.tiles[i];
    const double v = values[i];
    const std::string c = std::isfinite(v) ? colour(v) : std::string("#cfcfcf");
    double hi = -1e300;
    for (int k = 0; k < t.corners; ++k) hi = std::max(hi, t.theta_deg[k]);
    for (double shift : {0.0, -360.0}) {
      if (shift < 0 && hi <= 360.0) break;
      s << "<polygon points='";
      for (int k = 0; k < t.corners; ++k)
        s << Num(f.X(t.theta_deg[k] + shift), 1) << ',' << Num(f.Y(t.z_m[k]), 1) << (k + 1 < t.corners ? " " : "");
      s << "' fill='" << c << "' stroke='" << c << "'";
      if (std::isfinite(v))
        s << "><title>" << Num(v, 2) << ' ' << unit << "</title></polygon>";
      else
        s << "/>";
    }
  }
  s << "</g>";
  // Axes: theta every 45 degrees, z at 5 levels.
  s << "<g font-size='10' fill='#333'>";
  const double step = (f.theta_hi - f.theta_lo) > 120 ? 45 : 10;
  for (double th = std::ceil(f.theta_lo / step) * step; th <= f.theta_hi + 1e-9; th += step) {
    s << "<line x1='" << Num(f.X(th), 1) << "' x2='" << Num(f.X(th), 1) << "' y1='" << f.mt + f.h << "' y2='" << f.mt + f.h + 4
      << "' stroke='#333'/><text x='" << Num(f.X(th), 1) << "' y='" << f.mt + f.h + 15 << "' text-anchor='middle'>" << Num(th, 0)
      << "</text>";
  }
  s << "<text x='" << Num(f.ml + f.w / 2, 0) << "' y='" << Num(f.Height() - 3, 0)
    << "' text-anchor='middle'>&theta; around the liner (deg)</text>";
  for (int k = 0; k <= 4; ++k) {
    const double z = f.z_lo + (f.z_hi - f.z_lo) * k / 4.0;
    s << "<line x1='" << f.ml - 4 << "' x2='" << f.ml << "' y1='" << Num(f.Y(z), 1) << "' y2='" << Num(f.Y(z), 1)
      << "' stroke='#333'/><text x='" << f.ml - 6 << "' y='" << Num(f.Y(z) + 3, 1) << "' text-anchor='end'>" << Num(z, 2)
      << "</text>";
  }
  s << "<text x='10' y='" << Num(f.mt + f.h / 2, 0) << "' transform='rotate(-90 10 " << Num(f.mt + f.h / 2, 0)
    << ")' text-anchor='middle'>z (m)</text></g>";
  // Mismatch regions: dashed outlines (a region across theta = 0 in two pieces).
  for (const Region* r : regions) {
    const bool sensor = r->source.rfind("sensor:", 0) == 0;
    if (sensor) {
      const double th = r->theta_min_deg <= r->theta_max_deg ? 0.5 * (r->theta_min_deg + r->theta_max_deg)
                                                             : std::fmod(0.5 * (r->theta_min_deg + r->theta_max_deg + 360), 360);
      s << "<circle cx='" << Num(f.X(th), 1) << "' cy='" << Num(f.Y(0.5 * (r->z_min_m + r->z_max_m)), 1)
        << "' r='10' fill='none' stroke='#000' stroke-width='1.5' stroke-dasharray='4,2'><title>mismatch (" << Esc(r->sign)
        << ", " << Num(r->size_mm) << " mm) " << Esc(r->source) << "</title></circle>";
      continue;
    }
    std::vector<std::pair<double, double>> spans;
    if (r->theta_min_deg <= r->theta_max_deg)
      spans.push_back({r->theta_min_deg, r->theta_max_deg});
    else
      spans = {{r->theta_min_deg, 360.0}, {0.0, r->theta_max_deg}};
    for (const auto& [a, b] : spans) {
      s << "<rect x='" << Num(f.X(a), 1) << "' y='" << Num(f.Y(r->z_max_m), 1) << "' width='" << Num(f.X(b) - f.X(a), 1)
        << "' height='" << Num(f.Y(r->z_min_m) - f.Y(r->z_max_m), 1)
        << "' fill='none' stroke='#000' stroke-width='1.8' stroke-dasharray='6,3'><title>mismatch region (" << Esc(r->sign)
        << ", " << Num(r->size_mm) << " mm) " << Esc(r->source) << "</title></rect>";
    }
  }
  for (const Marker& m : markers) {
    const double x = f.X(m.theta), y = f.Y(m.z);
    s << "<circle cx='" << Num(x, 1) << "' cy='" << Num(y, 1) << "' r='4.5' fill='" << m.fill
      << "' stroke='#000' stroke-width='1.2'><title>" << Esc(m.id) << (m.title.empty() ? "" : ": ") << Esc(m.title)
      << "</title></circle><text x='" << Num(x + 6, 1) << "' y='" << Num(y - 5, 1) << "' font-size='10' class='halo'>"
      << Esc(m.id) << (m.value.empty() ? "" : ": ") << Esc(m.value) << "</text>";
  }
  if (thinnest) {
    const double x = f.X(thinnest->theta_deg), y = f.Y(thinnest->z_m);
    s << "<g stroke='#000' stroke-width='2.5'><line x1='" << Num(x - 7, 1) << "' y1='" << Num(y - 7, 1) << "' x2='"
      << Num(x + 7, 1) << "' y2='" << Num(y + 7, 1) << "'/><line x1='" << Num(x - 7, 1) << "' y1='" << Num(y + 7, 1) << "' x2='"
      << Num(x + 7, 1) << "' y2='" << Num(y - 7, 1) << "'/></g>";
    const bool left = x > f.ml + 0.7 * f.w, below = y < f.mt + 0.5 * f.h;
    s << "<text x='" << Num(left ? x - 9 : x + 9, 1) << "' y='" << Num(below ? y + 18 : y - 10, 1) << "' text-anchor='"
      << (left ? "end" : "start") << "' font-size='11' font-weight='bold' class='halo'>thinnest "
      << Num(thinnest->thickness_mm, 1) << " mm</text>";
  }
  s << "</svg>";
  return s.str();
}

// Horizontal colour bar with ticks: from lo to hi in `unit`.
std::string Legend(const std::function<std::string(double)>& colour, double lo, double hi, const std::string& caption) {
  const double w = 300, x0 = 20;
  std::ostringstream s;
  s << "<svg xmlns='http://www.w3.org/2000/svg' class='legend' width='" << w + 2 * x0 + 140 << "' height='46'>";
  const int n = 60;
  for (int k = 0; k < n; ++k) {
    const double v = lo + (hi - lo) * (k + 0.5) / n;
    s << "<rect x='" << Num(x0 + w * k / n, 2) << "' y='4' width='" << Num(w / n + 0.6, 2) << "' height='12' fill='" << colour(v)
      << "'/>";
  }
  s << "<rect x='" << x0 << "' y='4' width='" << w << "' height='12' fill='none' stroke='#666'/>";
  const double range = hi - lo;
  const int digits = range >= 20 ? 0 : range >= 2 ? 1 : 2;
  for (int k = 0; k <= 4; ++k) {
    const double v = lo + range * k / 4.0;
    s << "<text x='" << Num(x0 + w * k / 4.0, 1) << "' y='28' font-size='10' text-anchor='middle'>"
      << (v > 1e-9 && lo < 0 ? "+" : "") << (std::fabs(v) < 1e-9 ? std::string("0") : Num(v, digits)) << "</text>";
  }
  s << "<text x='" << x0 << "' y='42' font-size='10'>" << caption << "</text></svg>";
  return s.str();
}

double Interpolate(const std::vector<double>& xs, const std::vector<double>& ys, double x) {
  const size_t n = std::min(xs.size(), ys.size());
  if (n == 0) return std::nan("");
  if (x <= xs[0]) return ys[0];
  for (size_t i = 1; i < n; ++i)
    if (x <= xs[i]) return ys[i - 1] + (ys[i] - ys[i - 1]) * (x - xs[i - 1]) / std::max(xs[i] - xs[i - 1], 1e-12);
  return ys[n - 1];
}

// Measured minus predicted wear at a sensor's latest used reading up to `day` (mm): the measured
// thickness is the interval centre (reading + 0.5). NaN when the sensor has no such reading.
struct SensorResidual {
  double day = std::nan(""), before = std::nan(""), after = std::nan(""), reading = std::nan("");
};
SensorResidual ResidualAt(const SensorCurve& c, double day) {
  SensorResidual r;
  for (size_t k = 0; k < c.reading_days.size(); ++k) {
    if (!c.reading_used[k] || c.reading_days[k] > day + 1e-6 || !std::isfinite(c.reading_mm[k])) continue;
    if (!std::isfinite(r.day) || c.reading_days[k] >= r.day) {
      r.day = c.reading_days[k];
      r.reading = c.reading_mm[k];
    }
  }
  if (!std::isfinite(r.day)) return r;
  const double measured = r.reading + 0.5;
  r.before = Interpolate(c.model_days, c.baseline_thickness_mm, r.day) - measured;
  r.after = Interpolate(c.model_days, c.improved_thickness_mm, r.day) - measured;
  return r;
}

std::string ResidualMaps(int& ids, const DiagnosisResult& r, const LinerSnapshot& snap, const MapFrame& frame) {
  const LinerReport& L = r.liner;
  const double day = core::DaysBetween(r.installed_at, snap.time);
  const bool scan = !snap.measured_mm.empty();
  std::vector<double> before(L.tiles.size(), std::nan("")), after(L.tiles.size(), std::nan("")), mags;
  if (scan) {
    for (size_t i = 0; i < L.tiles.size() && i < snap.measured_mm.size(); ++i) {
      before[i] = snap.measured_mm[i] - snap.baseline_mm[i];
      after[i] = snap.measured_mm[i] - snap.improved_mm[i];
      if (std::isfinite(before[i])) mags.push_back(std::fabs(before[i]));
      if (std::isfinite(after[i])) mags.push_back(std::fabs(after[i]));
    }
  }
  std::vector<Marker> mb, ma;
  std::vector<double> sensor_mags;
  for (const SensorCurve& c : r.curves) {
    const SensorResidual sr = ResidualAt(c, day);
    if (std::isfinite(sr.before)) sensor_mags.push_back(std::fabs(sr.before));
    if (std::isfinite(sr.after)) sensor_mags.push_back(std::fabs(sr.after));
  }
  const double scale = std::max(0.5, NiceCeil(Quantile(scan ? mags : sensor_mags, 0.95)));
  auto div = [scale](double v) { return Diverging(v / scale); };
  for (const SensorCurve& c : r.curves) {
    const SensorResidual sr = ResidualAt(c, day);
    Marker m{c.sensor_id, c.theta_deg, c.z_m, "#fff", "", ""};
    m.title = std::isfinite(sr.day) ? "reading " + Num(sr.reading, 0) + " mm on day " + Num(sr.day, 1) : "no reading used";
    Marker m2 = m;
    if (std::isfinite(sr.before)) {
      // Model thickness - measured thickness = measured wear - predicted wear: + wore more (red).
      m.fill = div(sr.before);
      m.title += ", measured - predicted wear " + Num(sr.before, 2) + " mm";
      m2.fill = div(sr.after);
      m2.title += ", measured - predicted wear " + Num(sr.after, 2) + " mm";
      if (!scan) {
        m.value = Signed(sr.before, 1);
        m2.value = Signed(sr.after, 1);
      }
    }
    mb.push_back(m);
    ma.push_back(m2);
  }
  std::vector<const Region*> regions;
  for (const Region& g : r.regions)
    if (g.source.rfind("sensor:", 0) == 0 || g.source == snap.source) regions.push_back(&g);

  std::ostringstream h;
  if (scan) {
    h << "<h3>Scan " << Esc(snap.source.substr(5)) << " (" << Date(snap.time) << ", day " << Num(day, 0) << ")</h3>";
    h << "<p class='caption'>Each face of the liner, unwrapped (&theta; across, height z up), coloured by "
         "<b>measured minus predicted wear</b> in mm: <span class='red'>red</span> = the liner wore <b>more</b> than "
         "the model says (thinner than predicted), <span class='blue'>blue</span> = less. Left: the baseline "
         "(plain Eq. 9, before the diagnosis); "
      << AfterWords(r)
      << ". Same colour scale; values "
         "beyond "
         "&plusmn;"
      << Sig(scale)
      << " mm are drawn at the end colour. Grey: no scan points on the face. Circles: "
         "sensors (filled with their own residual at their latest reading up to the scan). Dashed outlines: the "
         "located mismatch regions. Hover a face for its value.</p>";
  } else {
    h << "<h3>No scan: sensor residuals on the predicted wear (" << Date(snap.time) << ", day " << Num(day, 0) << ")</h3>";
    h << "<p class='caption'>This campaign has no laser scan, so residuals are known <b>only at the sensors</b>. "
         "Background: the wear each model predicts at the latest reading (mm, pale = little, dark = much). Circles: "
         "the sensors, labelled and filled with <b>measured minus predicted wear</b> (mm) at their latest reading (<span "
         "class='red'>red</span> = wore more than predicted, <span class='blue'>blue</span> = less; same scale, "
         "&plusmn;"
      << Sig(scale) << " mm). Left: baseline (plain Eq. 9); " << AfterWords(r)
      << ". "
         "Dashed circles: sensors whose readings ran away from the baseline (mismatch regions).</p>";
  }
  h << "<div class='maps pair'>";
  if (scan) {
    h << LinerMap(ids, L, frame, before, div, "BEFORE: baseline (plain Eq. 9)", "mm", mb, regions, nullptr);
    h << LinerMap(ids, L, frame, after, div, "AFTER: " + AfterTitle(r), "mm", ma, regions, nullptr);
  } else {
    double wmax = 1;
    for (double v : snap.baseline_mm)
      if (std::isfinite(v)) wmax = std::max(wmax, v);
    for (double v : snap.improved_mm)
      if (std::isfinite(v)) wmax = std::max(wmax, v);
    wmax = NiceCeil(wmax);
    auto seq = [wmax](double v) { return Sequential(v / wmax); };
    h << LinerMap(ids, L, frame, snap.baseline_mm, seq, "BEFORE: baseline (plain Eq. 9), predicted wear", "mm wear", mb, regions,
                  nullptr);
    h << LinerMap(ids, L, frame, snap.improved_mm, seq, "AFTER: " + AfterTitle(r) + ", predicted wear", "mm wear", ma, regions,
                  nullptr);
    h << "</div><div class='maps'>" << Legend(seq, 0, wmax, "background: predicted wear (mm)");
  }
  if (scan) h << "</div><div class='maps'>";
  h << Legend(div, -scale, scale,
              "measured - predicted wear (mm): <tspan fill='#b2182b'>+ wore more than predicted</tspan>, "
              "<tspan fill='#2166ac'>- less</tspan>");
  h << "</div>";
  if (scan) {
    // Summary numbers of the two maps.
    auto rms = [](const std::vector<double>& v) {
      double sq = 0;
      size_t n = 0;
      for (double x : v)
        if (std::isfinite(x)) {
          sq += x * x;
          ++n;
        }
      return n ? std::sqrt(sq / static_cast<double>(n)) : std::nan("");
    };
    h << "<p>Per-face RMS of measured - predicted wear on this scan: before " << Num(rms(before)) << " mm, after "
      << Num(rms(after)) << " mm.</p>";
  }
  return h.str();
}

std::string ThinnestSection(int& ids, const DiagnosisResult& r, const MapFrame& frame) {
  const LinerReport& L = r.liner;
  std::ostringstream h;
  h << "<h2 id='thinnest'>Thinnest point</h2>";
  if (L.thinnest.empty()) {
    h << "<p>Not available (no usable sensor readings or no map).</p>";
    return h.str();
  }
  if (!L.thinnest_area.empty())
    h << "<p><b>The number to act on</b>, the thinnest area the data support (the smallest area whose band is narrow "
         "enough, else the sensors' own thinnest reading; the dashboard's headline and the reline dates use it): "
      << Esc(L.thinnest_area) << ".</p>";
  h << "<table><tr><th>from</th><th>date</th><th>remaining thickness (mm)</th><th>band (2 sd, mm)</th>"
       "<th>&theta; (deg)</th><th>z (m)</th><th>row</th><th>status</th></tr>";
  for (const ThinnestPoint& p : L.thinnest) {
    const bool band = std::isfinite(p.lo_mm) && std::isfinite(p.hi_mm);
    h << "<tr><td>" << Esc(p.label) << "</td><td>" << Date(p.time) << "</td><td class='num'><b>" << Num(p.thickness_mm, 1)
      << "</b></td><td class='num'>"
      << (band ? Num(p.lo_mm, 1) + " .. " + Num(p.hi_mm, 1) + " (" + Num(p.thickness_mm, 1) + " &plusmn; " +
                     Num(0.5 * (p.hi_mm - p.lo_mm), 1) + ")"
               : std::string("not computed for a model prediction"))
      << "</td><td class='num'>" << Num(p.theta_deg, 0) << "</td><td class='num'>" << Num(p.z_m, 3) << "</td><td>"
      << Esc(p.row.empty() ? "(outside the rows)" : p.row) << "</td><td>" << Esc(p.status)
      << (p.status_detail.empty() ? "" : ": ") << Esc(p.status_detail) << "</td></tr>";
  }
  h << "</table>";
  h << "<p class='caption'>The first line is the thinnest single face of the live Eq. 9 reconstruction from each "
       "sensor's latest valid reading (readings flagged as faults below are left out), with the band inside which the "
       "true thinnest face lies when every face is within 2 standard deviations (map noise, 1 mm sensor quantisation, "
       "row scale): a face of a noisy DEM map, whose band is often most of the liner. The model lines show where the diagnosis' "
       "baseline and improved models put the thinnest face "
       "at the same time; a large difference between them means the findings matter for the reline date. Minimum "
       "allowed thickness: "
    << Num(L.thickness_min_mm, 1) << " mm (as new " << Num(L.thickness_new_mm, 1) << " mm).</p>";
  if (!L.reline.empty()) {
    h << "<h3>Reline by (core forecast, per row)</h3><table><tr><th>row</th><th>reaches " << Num(L.thickness_min_mm, 1)
      << " mm</th><th>earliest</th><th>latest</th><th>note</th></tr>";
    for (const RelineDate& d : L.reline) {
      auto date = [](const std::optional<core::TimePoint>& t) { return t ? Date(*t) : std::string("-"); };
      h << "<tr><td>" << Esc(d.row) << "</td><td><b>" << date(d.reach) << "</b></td><td>" << date(d.earliest) << "</td><td>"
        << date(d.latest) << "</td><td>" << Esc(d.ok ? d.note : (d.note.empty() ? "no forecast" : d.note)) << "</td></tr>";
    }
    h << "</table><p class='caption'>The row's thinnest face carried along its sensors' fitted wear curves (the "
         "same forecast as the dashboard, plain Eq. 9: it does not use the findings). Earliest/latest: the band "
         "of the thinnest point and of the curves. '-': not reached within the forecast horizon or too few "
         "readings.</p>";
  }
  if (!L.remaining_now_mm.empty()) {
    const ThinnestPoint& p = L.thinnest.front();
    // Colour range: from the thinnest face (rounded down to 5 mm) to as new, so the pattern shows.
    double thin = L.thickness_new_mm;
    for (double v : L.remaining_now_mm)
      if (std::isfinite(v)) thin = std::min(thin, v);
    const double top = std::max(L.thickness_new_mm, 1.0);
    const double bottom = std::clamp(5.0 * std::floor(thin / 5.0), 0.0, top - 1.0);
    auto seq = [top, bottom](double v) { return Sequential((top - v) / (top - bottom)); };
    std::vector<Marker> markers;
    for (const SensorCurve& c : r.curves) markers.push_back({c.sensor_id, c.theta_deg, c.z_m, "#fff", c.row, ""});
    h << "<div class='maps'>"
      << LinerMap(ids, L, frame, L.remaining_now_mm, seq, "Remaining thickness on " + Date(L.now) + " (live reconstruction)",
                  "mm remaining", markers, {}, &p)
      << Legend(seq, bottom, top, "remaining thickness (mm): dark = thin") << "</div>";
  }
  return h.str();
}

std::string SensorPlot(const SensorCurve& c) {
  const double w = 320, h = 200, ml = 40, mr = 8, mt = 18, mb = 26;
  double tmax = 1, ymin = 1e300, ymax = -1e300;
  for (double t : c.reading_days) tmax = std::max(tmax, t);
  for (double t : c.model_days) tmax = std::max(tmax, t);
  auto span = [&](const std::vector<double>& v) {
    for (double y : v)
      if (std::isfinite(y)) {
        ymin = std::min(ymin, y);
        ymax = std::max(ymax, y);
      }
  };
  span(c.reading_mm);
  span(c.baseline_thickness_mm);
  span(c.improved_thickness_mm);
  if (ymin > ymax) {
    ymin = 0;
    ymax = 1;
  }
  ymax = std::min(ymax, c.thickness_new_mm + 2);
  ymin = std::max(ymin, -2.0);
  if (ymax - ymin < 2) ymax = ymin + 2;
  auto X = [&](double t) { return ml + (w - ml - mr) * t / tmax; };
  auto Y = [&](double y) { return mt + (h - mt - mb) * (ymax - y) / (ymax - ymin); };
  std::ostringstream s;
  s << "<svg xmlns='http://www.w3.org/2000/svg' width='" << w << "' height='" << h << "' class='plot'>";
  s << "<text x='" << ml << "' y='12' font-size='11'>" << Esc(c.sensor_id) << " (" << Esc(c.row) << ", &theta; "
    << Num(c.theta_deg, 0) << " deg, z " << Num(c.z_m, 2) << " m)</text>";
  if (!c.used)
    s << "<text x='" << ml + 6 << "' y='" << mt + 14 << "' font-size='11' fill='#c62828'>not used by the fit: why in the table "
      << "below</text>";
  s << "<rect x='" << ml << "' y='" << mt << "' width='" << (w - ml - mr) << "' height='" << (h - mt - mb)
    << "' fill='none' stroke='#999'/>";
  for (int k = 0; k <= 4; ++k) {
    const double y = ymin + (ymax - ymin) * k / 4.0;
    s << "<text x='2' y='" << Y(y) + 3 << "' font-size='9'>" << Num(y, 0) << "</text>";
    const double t = tmax * k / 4.0;
    s << "<text x='" << X(t) - 6 << "' y='" << h - 12 << "' font-size='9'>" << Num(t, 0) << "</text>";
  }
  s << "<text x='" << (w / 2) << "' y='" << h - 2 << "' font-size='9'>days; mm thickness</text>";
  const size_t stride = std::max<size_t>(1, c.reading_days.size() / 400);
  for (size_t i = 0; i < c.reading_days.size(); i += stride) {
    const double y = c.reading_mm[i];
    if (!std::isfinite(y) || y < ymin - 1 || y > ymax + 1) continue;
    s << "<circle cx='" << Num(X(c.reading_days[i]), 1) << "' cy='" << Num(Y(y), 1) << "' r='1.3' fill='"
      << (c.reading_used[i] ? "#333" : "#e33") << "'/>";
  }
  auto line = [&](const std::vector<double>& ys, const char* colour, const char* dash) {
    s << "<polyline fill='none' stroke='" << colour << "' stroke-width='1.5' stroke-dasharray='" << dash << "' points='";
    for (size_t i = 0; i < c.model_days.size() && i < ys.size(); ++i)
      s << Num(X(c.model_days[i]), 1) << "," << Num(Y(ys[i]), 1) << " ";
    s << "'/>";
  };
  line(c.baseline_thickness_mm, "#888", "5,3");
  line(c.improved_thickness_mm, "#1565c0", "none");
  s << "</svg>";
  return s.str();
}

std::string GridPlot(const ResidualGrid& g, const std::vector<double>& v, const std::string& title, bool diverging,
                     double scale) {
  const double cw = std::max(4.0, std::min(14.0, 480.0 / std::max<double>(1.0, static_cast<double>(g.ntheta))));
  const double ch = std::max(4.0, std::min(14.0, 240.0 / std::max<double>(1.0, static_cast<double>(g.nz))));
  const double ml = 40, mt = 18;
  const double w = ml + cw * static_cast<double>(g.ntheta) + 10, h = mt + ch * static_cast<double>(g.nz) + 30;
  std::ostringstream s;
  s << "<svg xmlns='http://www.w3.org/2000/svg' width='" << w << "' height='" << h << "'>";
  s << "<text x='" << ml << "' y='12' font-size='11'>" << Esc(title) << " (scale &plusmn;" << Num(scale, 1) << " mm)</text>";
  for (size_t iz = 0; iz < g.nz; ++iz) {
    for (size_t it = 0; it < g.ntheta; ++it) {
      const double x = v[iz * g.ntheta + it];
      if (!std::isfinite(x)) continue;
      const std::string colour = diverging ? Diverging(x / scale) : Sequential(x / scale);
      s << "<rect x='" << Num(ml + cw * static_cast<double>(it), 1) << "' y='"
        << Num(mt + ch * static_cast<double>(g.nz - 1 - iz), 1) << "' width='" << Num(cw, 1) << "' height='" << Num(ch, 1)
        << "' fill='" << colour << "'><title>" << Num(x, 2) << " mm</title></rect>";
    }
  }
  s << "<text x='2' y='" << mt + 8 << "' font-size='9'>z " << Num(g.z_max_m, 2) << "</text>";
  s << "<text x='2' y='" << mt + ch * static_cast<double>(g.nz) << "' font-size='9'>z " << Num(g.z_min_m, 2) << "</text>";
  s << "<text x='" << ml << "' y='" << h - 6 << "' font-size='9'>&theta; " << Num(g.theta_min_deg, 0) << " .. "
    << Num(g.theta_max_deg, 0) << " deg</text>";
  s << "</svg>";
  return s.str();
}

// Every sensor: used or why not; a used one's residual beside the noise the mismatch test allows.
std::string SensorNoiseTable(const DiagnosisResult& r) {
  if (r.sensors.empty()) return "";
  std::ostringstream h;
  h << "<h3 id='sensor-noise'>Sensors: residual and noise</h3><p class='caption'>At each sensor's latest loop crossing: "
       "<b>measured minus predicted wear</b> of the baseline (plain Eq. 9; + = the liner wore more than predicted), beside "
       "the standard deviation the mismatch test allows there, and that noise's parts (each a standard deviation; the "
       "total is their root sum of squares): the map's pattern error (what the smoothed DEM map misses beyond its "
       "sampling noise, relative to the predicted wear), the map's sampling noise at the sensor, the 2 % per-sensor "
       "floor, and the reading's own (1 mm loops, report interval). A residual within about 2 sd counts as noise: the "
       "largest part says where that noise comes from. <i>Map's own sd</i>: the DEM map model's standard error of the "
       "predicted wear at the sensor (its sampling noise and its smoothing's error there) and why it has that size "
       "there. <i>Refit's map error</i>: what the refit baseline (the "
       "&quot;after&quot; of a campaign without findings) took up at the sensor, against its prior sd.</p>";
  h << "<table><tr><th>sensor</th><th>used</th><th>day</th><th>measured - predicted wear (mm)</th><th>noise sd (mm)</th>"
       "<th>|residual| / sd</th><th>map pattern / map sampling / floor / reading (mm)</th><th>largest part</th>"
       "<th>map's own sd (mm) and why</th><th>refit's map error (prior sd)</th></tr>";
  for (const SensorNoise& n : r.sensors) {
    h << "<tr><td>" << Esc(n.sensor_id) << "</td>";
    if (!n.used) {
      h << "<td colspan='9'><b>not used</b>: "
        << Esc(n.excluded_because.empty() ? std::string("(no reason recorded)") : n.excluded_because) << "</td></tr>";
      continue;
    }
    if (!std::isfinite(n.residual_mm)) {
      h << "<td>yes</td><td colspan='8'>no loop crossing to compare</td></tr>";
      continue;
    }
    h << "<td>yes</td><td class='num'>" << Num(n.day, 0) << "</td><td class='num'>" << Signed(n.residual_mm, 1)
      << "</td><td class='num'>" << Num(n.noise_sd_mm, 1) << "</td><td class='num'>" << Num(std::fabs(n.z), 1)
      << "</td><td class='num'>" << Num(n.map_pattern_mm, 1) << " / " << Num(n.map_sampling_mm, 1) << " / "
      << Num(n.sensor_floor_mm, 1) << " / " << Num(n.reading_mm, 1) << "</td><td>" << Esc(n.noise_detail) << "</td><td><b>"
      << Num(n.map_sd_mm, 1) << "</b>: " << Esc(n.map_error_detail) << "</td><td class='num'>"
      << Signed(100 * n.refit_map_error_relative, 0) << " % (" << Num(100 * n.map_error_prior_relative, 0) << " %)</td></tr>";
  }
  h << "</table>";
  return h.str();
}

// The verdict (DescribeVerdict) with its headline coloured by what it says: green only for a
// tested "no mismatch", amber where nothing was tested, red for a mismatch.
std::string VerdictHtml(const DiagnosisResult& r) {
  const Verdict v = DescribeVerdict(r);
  const char* cls = v.kind == "no_mismatch"                                            ? "good"
                    : v.kind == "not_testable" || v.kind == "noise_model_does_not_fit" ? "warn"
                                                                                       : "bad";
  return "<b class='" + std::string(cls) + "' data-verdict='" + Esc(v.kind) + "'>" + Esc(v.headline) + "</b>: " + Esc(v.detail);
}

// The used sensors whose residual is large (beyond 1 sd of the test's noise or of the map's own
// standard error; at least the largest), largest first, at most `n`: each with its explanation.
std::string LargeResiduals(const DiagnosisResult& r, size_t n) {
  const std::vector<const SensorNoise*> v = ByResidual(r);
  std::string s;
  for (size_t k = 0; k < v.size() && k < n; ++k) {
    const SensorNoise& x = *v[k];
    const bool large = std::fabs(x.residual_mm) > x.noise_sd_mm || std::fabs(x.residual_mm) > x.map_sd_mm;
    if (k > 0 && !large) break;
    s += "<li>" + Esc(x.explanation) + ".</li>";
  }
  return s.empty() ? s : "<ul class='residuals'>" + s + "</ul>";
}

std::string EvidenceTable(const nlohmann::ordered_json& e) {
  if (!e.is_object() || e.empty()) return "";
  auto num = [&](const char* k, int d) {
    return e.contains(k) && e[k].is_number() ? Num(e[k].get<double>(), d) : std::string("-");
  };
  std::ostringstream s;
  s << "<table class='evidence'>";
  if (e.contains("delta_bic"))
    s << "<tr><td>information gain over the baseline (&Delta;BIC, > 10 needed)</td><td class='num'>" << num("delta_bic", 1)
      << "</td></tr>";
  if (e.contains("chi2_model"))
    s << "<tr><td>&chi;&sup2; baseline &rarr; model (" << num("observations", 0) << " observations)</td><td class='num'>"
      << num("chi2_baseline", 1) << " &rarr; " << num("chi2_model", 1) << "</td></tr>";
  if (e.contains("holdout_chi2_model"))
    s << "<tr><td>held-out &chi;&sup2; baseline &rarr; model (data the fit did not see)</td><td class='num'>"
      << num("holdout_chi2_baseline", 1) << " &rarr; " << num("holdout_chi2_model", 1) << "</td></tr>";
  if (e.contains("holdout_improvement"))
    s << "<tr><td>held-out improvement (> 3 % needed)</td><td class='num'>" << Num(100.0 * e.value("holdout_improvement", 0.0), 1)
      << " %</td></tr>";
  if (e.contains("residual_corr_normal_stress"))
    s << "<tr><td>baseline residual vs normal stress / vs worn depth (correlation)</td><td class='num'>"
      << num("residual_corr_normal_stress", 2) << " / " << num("residual_corr_depth", 2) << "</td></tr>";
  if (e.contains("mismatch_z_score"))
    s << "<tr><td>mismatch beyond the noise (chi-square excess, sigma)</td><td class='num'>" << num("mismatch_z_score", 1)
      << "</td></tr>";
  if (e.contains("step_mm"))
    s << "<tr><td>step seen by the sensor (mm) / its normal rate (mm/day)</td><td class='num'>" << num("step_mm", 1) << " / "
      << num("rate_mm_per_day", 3) << "</td></tr>";
  s << "</table>";
  return s.str();
}

}  // namespace

std::string RenderHtml(const DiagnosisResult& r) {
  int ids = 0;
  std::ostringstream h;
  h << "<!DOCTYPE html><html><head><meta charset='utf-8'><title>linerwatch diagnosis " << Esc(r.crusher_id)
    << "</title><style>body{font-family:sans-serif;margin:20px;max-width:1400px;color:#222}table{border-collapse:"
       "collapse;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 8px;font-size:13px;vertical-align:top;"
       "text-align:left}th{background:#f3f3f3}td.num{text-align:right;white-space:nowrap}.params td:nth-child(5){"
       "max-width:520px}.plots svg{margin:4px;border:1px solid #eee}.maps{display:flex;flex-wrap:wrap;gap:12px;"
       "align-items:flex-start}.maps svg.map{border:1px solid "
       "#ddd}.pair{flex-wrap:nowrap;overflow-x:auto}.caption{font-size:13px;color:#444;max-width:"
       "1150px}.good{color:#2e7d32}.bad{color:#c62828}.warn{color:#a15c00}.red{color:#b2182b;font-weight:bold}.blue{color:#"
       "2166ac;"
       "font-weight:bold}.summary{background:#f7f7f7;border:1px solid #ddd;padding:8px 14px;max-width:1150px}"
       ".halo{paint-order:stroke;stroke:#fff;stroke-width:3px}h3{margin-bottom:4px}</style></head><body>";
  h << "<h1>Diagnosis: " << Esc(r.crusher_id) << "</h1>";

  // --- At a glance ---
  h << "<div class='summary'><p>" << VerdictHtml(r) << "</p>";
  if (r.findings.empty()) {
    const std::string large = LargeResiduals(r, 3);
    if (!large.empty()) h << "<p>Where the residuals are largest, and the noise there:</p>" << large;
  }
  h << "<ul>";
  h << "<li>Installed " << Date(r.installed_at) << "; latest reading used " << Date(r.liner.now)
    << ". Mismatch test: chi-square excess " << Num(r.mismatch_z_score, 1) << " sigma over the noise model (real above 4).</li>";
  if (!r.liner.thinnest_area.empty())
    h << "<li><a href='#thinnest'>Thinnest area the data support</a> on " << Date(r.liner.now)
      << " (the dashboard's headline): " << Esc(r.liner.thinnest_area) << ".</li>";
  if (!r.liner.thinnest.empty()) {
    const ThinnestPoint& p = r.liner.thinnest.front();
    h << "<li>Thinnest single face of the live map on " << Date(p.time) << ": <b>" << Num(p.thickness_mm, 1) << " mm</b>";
    if (std::isfinite(p.lo_mm) && std::isfinite(p.hi_mm))
      h << " (band " << Num(p.lo_mm, 1) << " .. " << Num(p.hi_mm, 1) << " mm)";
    h << " at &theta; " << Num(p.theta_deg, 0) << " deg, z " << Num(p.z_m, 2) << " m"
      << (p.row.empty() ? "" : ", row " + Esc(p.row))
      << (r.liner.thinnest_area.empty() ? "" : ": one face of a noisy DEM map, for ParaView, not the number to act on")
      << ".</li>";
  }
  {
    const RelineDate* first = nullptr;
    for (const RelineDate& d : r.liner.reline)
      if (d.reach && (!first || *d.reach < *first->reach)) first = &d;
    if (first)
      h << "<li>Reline by <b>" << Date(*first->reach) << "</b> (row " << Esc(first->row) << "; earliest "
        << (first->earliest ? Date(*first->earliest) : std::string("-")) << ").</li>";
  }
  if (r.improved_model == ImprovedModel::kFindings) {
    h << "<li>Error of the prediction against the recordings (RMSE, mm of wear): baseline " << Num(r.baseline.rmse_mm)
      << " &rarr; with the findings " << Num(r.improved.rmse_mm) << " (held out: " << Num(r.baseline.holdout_rmse_mm)
      << " &rarr; " << Num(r.improved.holdout_rmse_mm) << ").</li>";
  } else {
    h << "<li>Error of the baseline against the recordings (RMSE, mm of wear): " << Num(r.baseline.rmse_mm) << " (held out "
      << Num(r.baseline.holdout_rmse_mm) << "). Nothing was found, so there is no improved model: the "
      << "<a href='#error'>&quot;after&quot;</a> figures (" << Num(r.improved.rmse_mm) << ", held out "
      << Num(r.improved.holdout_rmse_mm) << ") are " << Esc(ImprovedModelDescription(r.improved_model)) << ".</li>";
  }
  if (!r.data_quality.empty())
    h << "<li>" << r.data_quality.size() << " sensor data-quality issue(s): see <a href='#quality'>Data quality</a> "
      << "(faulty readings are left out, never read as physics).</li>";
  {
    size_t excluded = 0;
    for (const SensorNoise& n : r.sensors) excluded += n.used ? 0 : 1;
    if (excluded)
      h << "<li>" << excluded << " of " << r.sensors.size() << " sensors not used by the fit: <a href='#sensor-noise'>each "
        << "with its reason</a>.</li>";
  }
  if (!r.notes.empty()) h << "<li>Read the <a href='#notes'>notes</a>: they say which effects could not be tried.</li>";
  h << "</ul></div>";

  // --- Residual maps ---
  const MapFrame frame = FrameOf(r.liner);
  if (!r.liner.snapshots.empty()) {
    h << "<h2>Where the prediction misses: residual maps over the unwrapped liner</h2>";
    if (!r.liner.tiles_are_faces)
      h << "<p class='caption'>This map has more than " << kMaxLinerTiles
        << " faces: the maps show area-weighted means on a 2 deg raster.</p>";
    for (const LinerSnapshot& s : r.liner.snapshots) h << ResidualMaps(ids, r, s, frame);
  }

  h << ThinnestSection(ids, r, frame);

  // --- Findings with their parameters ---
  h << "<h2 id='findings'>Findings</h2>";
  if (r.findings.empty()) {
    const Verdict v = DescribeVerdict(r);
    h << "<p>No finding. "
      << (v.kind == "noise_model_does_not_fit" ? "The noise model does not fit these data (see the verdict above): nothing "
                                                 "was tested, so this is no evidence of agreement."
          : v.kind == "not_testable"
              ? "The noise is as large as the wear here (see the verdict above): the test could not have seen a mismatch."
              : "No mismatch beyond the noise model.")
      << " What the noise is at each sensor: <a href='#sensor-noise'>Sensors: residual and noise</a>.</p>";
  } else {
    int k = 1;
    for (const Finding& f : r.findings) {
      h << "<h3>" << k++ << ". " << Esc(EffectWords(f.effect)) << " <small>(<code>" << Esc(f.effect) << "</code>, confidence "
        << Num(f.confidence, 2) << ")</small></h3><p class='caption'>" << Esc(f.explanation) << "</p>";
      h << ParameterTable(f.parameters);
      h << EvidenceTable(f.evidence);
    }
  }

  h << LimitsSection(r);

  h << "<h2 id='error'>Error (mm of wear)</h2><table><tr><th></th><th>RMSE</th><th>max |error|</th><th>held-out RMSE</th>"
       "<th>observations</th></tr>";
  h << "<tr><td>baseline (plain Eq. 9, wear linear in time)</td><td class='num'>" << Num(r.baseline.rmse_mm)
    << "</td><td class='num'>" << Num(r.baseline.max_abs_mm) << "</td><td class='num'>" << Num(r.baseline.holdout_rmse_mm)
    << "</td><td class='num'>" << r.baseline.observations << "</td></tr>";
  h << "<tr><td>" << ImprovedWords(r) << "</td><td class='num'>" << Num(r.improved.rmse_mm) << "</td><td class='num'>"
    << Num(r.improved.max_abs_mm) << "</td><td class='num'>" << Num(r.improved.holdout_rmse_mm) << "</td><td class='num'>"
    << r.improved.observations << "</td></tr></table>";
  h << "<p class='caption'>Second line: " << Esc(ImprovedModelDescription(r.improved_model)) << "."
    << (r.improved_model == ImprovedModel::kFindings
            ? std::string("")
            : std::string(" Its errors are those of a fit to the data it is measured on (held out: of the same refit on "
                          "the folds); they are no evidence that anything was found or improved."))
    << "</p>";

  if (!r.regions.empty()) {
    h << "<h2>Mismatch regions</h2><p class='caption'>Where the baseline (refit to all data) misses beyond 3 sigma. "
         "<i>over</i>: the model predicts more wear than measured; <i>under</i>: less (the liner wore faster than "
         "predicted there).</p><table><tr><th>source</th><th>z (m)</th><th>&theta; (deg)</th><th>from</th>"
         "<th>to</th><th>sign</th><th>size (mm)</th></tr>";
    for (const Region& g : r.regions) {
      h << "<tr><td>" << Esc(g.source) << "</td><td class='num'>" << Num(g.z_min_m, 3) << " .. " << Num(g.z_max_m, 3)
        << "</td><td class='num'>" << Num(g.theta_min_deg, 1) << " .. " << Num(g.theta_max_deg, 1) << "</td><td>"
        << core::FormatIsoTime(g.from) << "</td><td>" << core::FormatIsoTime(g.to) << "</td><td>" << Esc(g.sign)
        << "</td><td class='num'>" << Num(g.size_mm) << "</td></tr>";
    }
    h << "</table>";
  }

  h << "<h2>Sensors: measured vs predicted thickness</h2><p class='caption'>Dots: readings (red: excluded as "
       "faults). Grey dashed: baseline. Blue: "
    << ImprovedWords(r) << ".</p><div class='plots'>";
  for (const SensorCurve& c : r.curves) h << SensorPlot(c);
  h << "</div>";
  h << SensorNoiseTable(r);

  h << "<h2 id='quality'>Data quality</h2>";
  if (r.data_quality.empty()) {
    h << "<p>No sensor fault found.</p>";
  } else {
    h << "<table><tr><th>sensor</th><th>issue</th><th>from</th><th>to</th><th>detail</th></tr>";
    for (const DataQualityIssue& d : r.data_quality)
      h << "<tr><td>" << Esc(d.sensor_id) << "</td><td>" << Esc(d.issue) << "</td><td>" << core::FormatIsoTime(d.from)
        << "</td><td>" << core::FormatIsoTime(d.to) << "</td><td>" << Esc(d.detail) << "</td></tr>";
    h << "</table>";
  }

  // --- Hypotheses, ranked ---
  h << "<h2 id='hypotheses'>Hypotheses tried, ranked</h2><p class='caption'>Every physical change of the wear law that was "
       "fitted, best supported first. A model is accepted when &Delta;BIC > 10, the held-out &chi;&sup2; improves "
       "by more than 4 and 3 %, and every effect's size is more than 2 standard errors from zero and not at the "
       "limit of its physical range (docs/diagnosis.md, section 5); a pair must also beat each of its effects alone. "
       "A rejected model names each test it failed, its value and what was needed: a large held-out improvement "
       "alone is not enough. Parameters in physical units.</p>";
  std::vector<const nlohmann::ordered_json*> hyps;
  for (const auto& hy : r.hypotheses) hyps.push_back(&hy);
  std::stable_sort(hyps.begin(), hyps.end(),
                   [](const auto* a, const auto* b) { return a->value("delta_bic", 0.0) > b->value("delta_bic", 0.0); });
  const std::string top_model =
      !r.findings.empty() && r.findings.front().evidence.contains("model") && r.findings.front().evidence["model"].is_string()
          ? r.findings.front().evidence["model"].get<std::string>()
          : "";
  h << "<table><tr><th>rank</th><th>model</th><th>&Delta;BIC</th><th>held-out improvement</th>"
       "<th>effect size (sd)</th><th>verdict</th><th>fitted parameters</th></tr>";
  int rank = 1;
  for (const auto* hy : hyps) {
    const std::string model = hy->value("model", "");
    const bool accepted = hy->value("accepted", false);
    std::string verdict =
        accepted ? (model == top_model ? "<b class='good'>accepted, chosen</b>" : "accepted") : "<b>rejected</b>";
    if (!accepted && hy->contains("rejected_because") && (*hy)["rejected_because"].is_string())
      verdict += ": " + Esc((*hy)["rejected_because"].get<std::string>());
    if (accepted && model != top_model && hy->contains("not_chosen_because") && (*hy)["not_chosen_because"].is_string())
      verdict += "; not chosen: " + Esc((*hy)["not_chosen_because"].get<std::string>());
    h << "<tr><td class='num'>" << rank++ << "</td><td>" << Esc(ModelWords(model)) << "</td><td class='num'>"
      << Num(hy->value("delta_bic", 0.0), 1) << "</td><td class='num'>" << Num(100.0 * hy->value("holdout_improvement", 0.0), 1)
      << " %</td><td class='num'>" << Num(hy->value("significance", 0.0), 1) << "</td><td>" << verdict << "</td><td>"
      << HypothesisParams(hy->contains("parameters") ? (*hy)["parameters"] : nlohmann::ordered_json(), r.liner.thickness_new_mm)
      << "</td></tr>";
  }
  h << "</table>";
  if (!r.hypotheses.empty()) {
    h << "<p><b>Verdict:</b> ";
    if (r.findings.empty())
      h << Esc(DescribeVerdict(r).headline) << "; no hypothesis accepted.";
    else if (r.findings.front().effect == kUnexplained)
      h << "<b>unexplained</b>: the mismatch is real but no hypothesis is convincing.";
    else
      h << Esc(EffectWords(r.findings.front().effect)) << ".";
    h << "</p>";
  }

  if (!r.grids.empty()) {
    h << "<details><summary>Scan cells as the fit saw them (refit baseline, model - measured)</summary>";
    for (const ResidualGrid& g : r.grids) {
      double scale = 0.5, mscale = 1;
      for (size_t i = 0; i < g.before_mm.size(); ++i) {
        if (std::isfinite(g.before_mm[i])) scale = std::max(scale, std::fabs(g.before_mm[i]));
        if (std::isfinite(g.measured_mm[i])) mscale = std::max(mscale, g.measured_mm[i]);
      }
      h << "<p>Scan " << Esc(g.scan_file) << " (" << Date(g.date)
        << "): cells of the fit. Here residual = model - "
           "measured (red: the model predicts more wear than measured, \"over\").</p><div class='plots'>";
      h << GridPlot(g, g.measured_mm, "measured wear", false, mscale);
      h << GridPlot(g, g.before_mm, "refit baseline - measured", true, scale);
      h << GridPlot(g, g.after_mm, "improved - measured", true, scale);
      h << "</div>";
    }
    h << "</details>";
  }

  if (!r.notes.empty()) {
    h << "<h2 id='notes'>Notes</h2><ul>";
    for (const std::string& n : r.notes) h << "<li>" << Esc(n) << "</li>";
    h << "</ul>";
  }
  h << "</body></html>\n";
  return h.str();
}

void WriteHtml(const std::filesystem::path& path, const DiagnosisResult& result) {
  core::WriteFileAtomically(path, RenderHtml(result));
}

}  // namespace lw::diagnosis
