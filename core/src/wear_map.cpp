#include "core/wear_map.hpp"

#include "core/atomic_file.hpp"

#include <algorithm>
#include <charconv>
#include <string_view>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>
#include <unordered_map>

#include <Eigen/Geometry>

namespace lw::core {

InputError::InputError(std::string file, size_t line, const std::string& rule)
    : std::runtime_error(file + (line ? ":" + std::to_string(line) : std::string()) + ": " + rule),
      file_(std::move(file)),
      line_(line),
      rule_(rule) {}

std::string ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.filename().string(), 0, "cannot open '" + path.string() + "'");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

namespace {

// Whitespace-separated tokens with their line numbers, read in place: a cursor over the text (a
// million-face map is ~9 million tokens; one std::string each made the parse 10x slower). The
// tokens are counted once up front, so a count that the rest of the file cannot hold is refused
// before anything is allocated for it.
class Tokens {
 public:
  /// The tokens of `text` from `offset` on, which is on line `line`.
  Tokens(const std::string& text, std::string file, size_t offset, size_t line)
      : text_(text), file_(std::move(file)), pos_(offset), line_(line) {
    bool in_token = false;
    for (size_t i = offset; i < text_.size(); ++i) {
      const bool space = Space(text_[i]);
      if (!space && !in_token) ++total_;
      in_token = !space;
    }
    SkipSpace();
  }
  bool done() const { return pos_ >= text_.size(); }
  /// Line of the next token (at the end: of the last one).
  size_t line() const { return done() ? last_line_ : line_; }
  std::string_view Peek() const { return done() ? std::string_view() : std::string_view(text_).substr(pos_, TokenEnd() - pos_); }
  std::string Next(const char* what) { return std::string(NextView(what)); }
  double Number(const char* what) {
    const size_t l = line();
    const std::string_view t = NextView(what);
    double v = 0;
    // A leading '+' (strtod reads it, from_chars does not); from_chars is correctly rounded, as
    // strtod is: the same double for every decimal.
    const char* b = t.data() + (t.size() > 1 && t[0] == '+' && t[1] != '-' && t[1] != '+' ? 1 : 0);
    const auto [end, ec] = std::from_chars(b, t.data() + t.size(), v);
    if (ec == std::errc::result_out_of_range) {
      // Beyond double's range: strtod's answer (+-HUGE_VAL, refused below; or a denormal or 0).
      v = std::strtod(std::string(t).c_str(), nullptr);
    } else if (ec != std::errc() || end != t.data() + t.size()) {
      throw InputError(file_, l, std::string(what) + " '" + std::string(t) + "' is not a number");
    }
    if (!std::isfinite(v)) throw InputError(file_, l, std::string(what) + " '" + std::string(t) + "' is not finite");
    return v;
  }
  long long Integer(const char* what) {
    const size_t l = line();
    const double v = Number(what);
    // Counts and indices of a VTK file are 32-bit (VTK's own vtkIdType may be 64-bit, but no mesh
    // linerwatch imports comes near 2^32 points).
    if (v != std::floor(v) || v < 0 || v > 4294967295.0) {
      throw InputError(file_, l, std::string(what) + " must be a whole number in [0, 4294967295]");
    }
    return static_cast<long long>(v);
  }
  /// A count of items of `per_item` values each that must still be in the file: refuses counts the
  /// file cannot hold before anything is allocated for them.
  size_t Count(const char* what, size_t per_item = 1) {
    const size_t l = line();
    const auto n = static_cast<size_t>(Integer(what));
    NeedValues(n, per_item, what, l);
    return n;
  }
  void NeedValues(size_t n, size_t per_item, const char* what, size_t l) const {
    const size_t left = Remaining();
    if (per_item != 0 && n > left / per_item) {
      throw InputError(file_, l,
                       std::string(what) + " " + std::to_string(n) + " needs " + std::to_string(per_item) +
                           " value(s) each but the file holds only " + std::to_string(left) + " more");
    }
  }
  InputError Error(const std::string& rule) const { return InputError(file_, line(), rule); }
  size_t Remaining() const { return total_ - consumed_; }
  // Line of the token just consumed (for messages about it).
  size_t LastLine() const { return consumed_ ? last_line_ : 0; }

 private:
  static bool Space(char c) { return c == ' ' || (c >= '\t' && c <= '\r'); }  // std::isspace in the C locale
  size_t TokenEnd() const {
    size_t j = pos_;
    while (j < text_.size() && !Space(text_[j])) ++j;
    return j;
  }
  void SkipSpace() {
    while (pos_ < text_.size() && Space(text_[pos_])) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
  }
  std::string_view NextView(const char* what) {
    if (done()) throw Error("file ends where " + std::string(what) + " was expected");
    const size_t end = TokenEnd();
    const std::string_view t = std::string_view(text_).substr(pos_, end - pos_);
    last_line_ = line_;
    ++consumed_;
    pos_ = end;
    SkipSpace();
    return t;
  }
  const std::string& text_;
  std::string file_;
  size_t pos_ = 0, line_ = 1, last_line_ = 0;
  size_t total_ = 0, consumed_ = 0;
};

/// A coordinate beyond this (m) is a units or export mistake (a gyratory concave is a few metres).
constexpr double kMaxCoordinateM = 1000;

std::string OutOfFrame(const Eigen::Vector3d& p) {
  char b[160];
  std::snprintf(b, sizeof b, "vertex (%g, %g, %g) is more than %g m from the crusher origin (metres, crusher frame?)", p.x(),
                p.y(), p.z(), kMaxCoordinateM);
  return b;
}

std::string NegativeWear(size_t face, double value) {
  char b[128];
  std::snprintf(b, sizeof b, "wear of face %zu is %g: wear intensity must be >= 0", face, value);
  return b;
}

void Assign(WearMap& map, const std::string& name, Eigen::VectorXd values) {
  if (name == "wear")
    map.wear = std::move(values);
  else if (name == "normal_stress_average")
    map.normal_stress = std::move(values);
  else if (name == "shear_stress_average")
    map.shear_stress = std::move(values);
  else if (name == "wear_stderr")
    map.wear_stderr = std::move(values);
  else
    map.extra[name] = std::move(values);
}

std::string TrimEnd(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  return s;
}

// The first three lines: the version (5.x may lay cells out as OFFSETS and CONNECTIVITY), the
// title and the encoding.
struct VtkHeader {
  bool v5 = false;
  std::string title;  // trimmed
  size_t body = 0;    // offset of line 4, where the tokens start
};

VtkHeader ReadHeader(const std::string& text, const std::string& file) {
  // Header: 4 lines, the title line is free text.
  std::istringstream hs(text);
  std::string l1, l2, l3;
  std::getline(hs, l1);
  std::getline(hs, l2);
  std::getline(hs, l3);
  if (l1.rfind("# vtk DataFile Version", 0) != 0)
    throw InputError(file, 1, "not a legacy VTK file (expected '# vtk DataFile Version')");
  // The legacy format's versions are 1.0 to 5.1: a later one may lay its data out otherwise.
  std::string version = l1.substr(std::strlen("# vtk DataFile Version"));
  while (!version.empty() && std::isspace(static_cast<unsigned char>(version.back()))) version.pop_back();
  while (!version.empty() && version.front() == ' ') version.erase(0, 1);
  const bool known = version.size() == 3 && version[1] == '.' && version[0] >= '1' && version[0] <= '5' &&
                     std::isdigit(static_cast<unsigned char>(version[2])) && (version[0] < '5' || version[2] <= '1');
  if (!known) throw InputError(file, 1, "VTK version '" + version + "' is not a legacy VTK version (1.0 to 5.1)");
  const int major = version[0] - '0';
  VtkHeader header;
  header.v5 = major == 5;
  if (TrimEnd(l3) != "ASCII") throw InputError(file, 3, "only ASCII legacy VTK is supported (found '" + TrimEnd(l3) + "')");
  header.title = TrimEnd(l2);
  for (int i = 0; i < 3; ++i) header.body = text.find('\n', header.body) + 1;
  return header;
}

void ReadTitle(WearMap& map, std::string title, const std::string& file) {
  map.title = std::move(title);
  // "linerwatch dem <case> windows=K ...": the number of independent time windows `wear` sums.
  if (const size_t at = map.title.find("windows="); at != std::string::npos) {
    const long k = std::strtol(map.title.c_str() + at + 8, nullptr, 10);
    if (k < 0 || k > 100000) throw InputError(file, 2, "title's windows=" + std::to_string(k) + " is not a window count");
    map.windows = static_cast<int>(k);
  }
}

// The body read so far: the map, and the data section (CELL_DATA or POINT_DATA) that the arrays
// which follow belong to.
struct VtkBody {
  VtkBody(const std::string& file_name, bool version_5) : file(file_name), v5(version_5) {}
  const std::string& file;
  bool v5;
  WearMap map;
  size_t cell_count = 0;
  bool in_cell_data = false, in_point_data = false;
  // A cell array given twice would have its last copy win unseen (a second "wear" further down).
  std::set<std::string> assigned;
  size_t point_data_count = 0;
};

void AssignOnce(VtkBody& body, const std::string& name, Eigen::VectorXd v, size_t line) {
  if (!body.assigned.insert(name).second) throw InputError(body.file, line, "cell array '" + name + "' appears twice");
  Assign(body.map, name, std::move(v));
}

void ReadPoints(Tokens& t, VtkBody& body) {
  const size_t n = t.Count("point count", 3);
  t.Next("point type");
  body.map.points.resize(n);
  for (auto& p : body.map.points) {
    p.x() = t.Number("x");
    p.y() = t.Number("y");
    p.z() = t.Number("z");
    if (p.cwiseAbs().maxCoeff() > kMaxCoordinateM) throw InputError(body.file, t.LastLine(), OutOfFrame(p));
  }
}

// VTK 5's cell layout: `a` offsets, then the CONNECTIVITY of `b` point indices they point into.
std::vector<std::array<uint32_t, 3>> ReadOffsetCells(Tokens& t, const std::string& file, const std::string& kw, size_t kw_line,
                                                     size_t a, size_t b) {
  std::vector<std::array<uint32_t, 3>> faces;
  t.Next("OFFSETS");
  t.Next("offset type");
  std::vector<long long> offsets(a);
  for (auto& o : offsets) o = t.Integer("offset");
  for (size_t i = 0; i < a; ++i) {
    if (static_cast<size_t>(offsets[i]) > b || (i > 0 && offsets[i] < offsets[i - 1])) {
      throw InputError(file, kw_line,
                       "OFFSETS must not decrease nor exceed the CONNECTIVITY size " + std::to_string(b) + " (offset " +
                           std::to_string(i) + " is " + std::to_string(offsets[i]) + ")");
    }
  }
  if (t.Next("CONNECTIVITY") != "CONNECTIVITY") throw InputError(file, t.LastLine(), "expected CONNECTIVITY after OFFSETS");
  t.Next("connectivity type");
  t.NeedValues(b, 1, "cell size", kw_line);
  std::vector<long long> conn(b);
  for (auto& c : conn) c = t.Integer("point index");
  for (size_t i = 0; i + 1 < a; ++i) {
    if (offsets[i] > offsets[i + 1] || offsets[i + 1] > static_cast<long long>(b)) {
      throw InputError(file, kw_line, "OFFSETS " + std::to_string(i + 1) + " is out of order or beyond the connectivity");
    }
    const long long k = offsets[i + 1] - offsets[i];
    if (kw == "POLYGONS" && k != 3)
      throw InputError(file, kw_line,
                       "polygon " + std::to_string(i) + " has " + std::to_string(k) + " vertices; only triangles are supported");
    if (kw == "POLYGONS") {
      faces.push_back({static_cast<uint32_t>(conn[offsets[i]]), static_cast<uint32_t>(conn[offsets[i] + 1]),
                       static_cast<uint32_t>(conn[offsets[i] + 2])});
    }
  }
  return faces;
}

// The classic cell layout: `a` cells, each its vertex count and then its point indices.
std::vector<std::array<uint32_t, 3>> ReadCountedCells(Tokens& t, const std::string& file, const std::string& kw, size_t a) {
  std::vector<std::array<uint32_t, 3>> faces;
  for (size_t i = 0; i < a; ++i) {
    const size_t line = t.line();
    const size_t k = t.Count("vertex count", 1);
    std::vector<uint32_t> idx(k);
    for (auto& v : idx) v = static_cast<uint32_t>(t.Integer("point index"));
    if (kw == "POLYGONS") {
      if (k != 3) throw InputError(file, line, "polygon with " + std::to_string(k) + " vertices; only triangles are supported");
      faces.push_back({idx[0], idx[1], idx[2]});
    }
  }
  return faces;
}

// POLYGONS are the map's faces; VERTICES, LINES and TRIANGLE_STRIPS are read and dropped.
void ReadCells(Tokens& t, VtkBody& body, const std::string& kw, size_t kw_line) {
  const size_t a = t.Count("cell count", 1);
  const size_t b = t.Count("cell size", 1);
  std::vector<std::array<uint32_t, 3>> faces =
      body.v5 && t.Peek() == "OFFSETS" ? ReadOffsetCells(t, body.file, kw, kw_line, a, b) : ReadCountedCells(t, body.file, kw, a);
  if (kw == "POLYGONS") body.map.faces = std::move(faces);
}

// Only single-component cell arrays go into the map; the others are read and dropped.
void ReadScalars(Tokens& t, VtkBody& body) {
  const std::string name = t.Next("array name");
  t.Next("data type");
  size_t ncomp = 1;
  if (t.Peek() != "LOOKUP_TABLE") ncomp = static_cast<size_t>(t.Integer("component count"));
  if (t.Next("LOOKUP_TABLE") != "LOOKUP_TABLE")
    throw InputError(body.file, t.LastLine(), "expected LOOKUP_TABLE after SCALARS " + name);
  t.Next("lookup table name");
  if (ncomp < 1 || ncomp > 9) throw InputError(body.file, t.LastLine(), "SCALARS " + name + ": component count must be 1-9");
  const size_t tuples = body.in_point_data ? body.point_data_count : body.cell_count;
  t.NeedValues(tuples, ncomp, name.c_str(), t.LastLine());
  const size_t n = tuples * ncomp;
  Eigen::VectorXd v(static_cast<Eigen::Index>(n));
  for (size_t i = 0; i < n; ++i) {
    v[static_cast<Eigen::Index>(i)] = t.Number(name.c_str());
    if (name == "wear" && v[static_cast<Eigen::Index>(i)] < 0)
      throw InputError(body.file, t.LastLine(), NegativeWear(i, v[static_cast<Eigen::Index>(i)]));
  }
  if (body.in_cell_data && ncomp == 1) AssignOnce(body, name, std::move(v), t.LastLine());
}

void ReadField(Tokens& t, VtkBody& body) {
  t.Next("field name");
  const auto arrays = t.Integer("array count");
  for (long long a = 0; a < arrays; ++a) {
    const size_t line = t.line();
    const std::string name = t.Next("array name");
    const size_t ncomp = t.Count("component count");
    const size_t ntuples = t.Count("tuple count", std::max<size_t>(ncomp, 1));
    t.Next("data type");
    if (body.in_cell_data && ntuples != body.cell_count) {
      throw InputError(
          body.file, line,
          "array '" + name + "' has " + std::to_string(ntuples) + " tuples but CELL_DATA is " + std::to_string(body.cell_count));
    }
    t.NeedValues(ntuples, ncomp, name.c_str(), line);
    Eigen::VectorXd v(static_cast<Eigen::Index>(ncomp * ntuples));
    for (Eigen::Index i = 0; i < v.size(); ++i) {
      v[i] = t.Number(name.c_str());
      if (name == "wear" && v[i] < 0) throw InputError(body.file, t.LastLine(), NegativeWear(static_cast<size_t>(i), v[i]));
    }
    if (body.in_cell_data && ncomp == 1) AssignOnce(body, name, std::move(v), line);
  }
}

void SkipVectors(Tokens& t, const VtkBody& body, const std::string& kw) {
  t.Next("array name");
  t.Next("data type");
  const size_t n = 3 * (body.in_point_data ? body.point_data_count : body.cell_count);
  if (n > t.Remaining()) throw t.Error(kw + " promises more values than the file holds");
  for (size_t i = 0; i < n; ++i) t.Number(kw.c_str());
}

// VTK 5.1 may add METADATA blocks (INFORMATION ...); skip to the next known keyword.
void SkipMetadata(Tokens& t) {
  while (!t.done()) {
    const std::string_view p = t.Peek();
    if (p == "CELL_DATA" || p == "POINT_DATA" || p == "SCALARS" || p == "FIELD" || p == "VECTORS") break;
    t.Next("metadata");
  }
}

// One keyword of the body and what belongs to it.
void ReadSection(Tokens& t, VtkBody& body) {
  const size_t kw_line = t.line();
  const std::string kw = t.Next("keyword");
  if (kw == "POINTS") {
    ReadPoints(t, body);
  } else if (kw == "POLYGONS" || kw == "VERTICES" || kw == "LINES" || kw == "TRIANGLE_STRIPS") {
    ReadCells(t, body, kw, kw_line);
  } else if (kw == "CELL_DATA") {
    body.cell_count = t.Count("cell data count", 0);  // checked per array (NeedValues)
    body.in_cell_data = true;
    body.in_point_data = false;
  } else if (kw == "POINT_DATA") {
    body.point_data_count = t.Count("point data count", 0);
    body.in_point_data = true;
    body.in_cell_data = false;
  } else if (kw == "SCALARS") {
    ReadScalars(t, body);
  } else if (kw == "FIELD") {
    ReadField(t, body);
  } else if (kw == "VECTORS" || kw == "NORMALS") {
    SkipVectors(t, body, kw);
  } else if (kw == "METADATA") {
    SkipMetadata(t);
  } else {
    throw InputError(body.file, kw_line, "unexpected keyword '" + kw + "'");
  }
}

// What holds only for the file as a whole: triangles, each on existing points, one wear per face.
void CheckWhole(const WearMap& map, size_t cell_count, const std::string& file) {
  if (map.faces.empty()) throw InputError(file, 0, "no triangles (POLYGONS) found");
  for (size_t i = 0; i < map.faces.size(); ++i) {
    for (uint32_t v : map.faces[i]) {
      if (v >= map.points.size())
        throw InputError(file, 0,
                         "triangle " + std::to_string(i) + " refers to point " + std::to_string(v) + " of " +
                             std::to_string(map.points.size()));
    }
  }
  if (cell_count != 0 && cell_count != map.faces.size()) {
    throw InputError(
        file, 0,
        "CELL_DATA count " + std::to_string(cell_count) + " differs from the triangle count " + std::to_string(map.faces.size()));
  }
  if (map.wear.size() == 0) throw InputError(file, 0, "no per-face array named 'wear' in CELL_DATA");
}

WearMap ParseVtk(const std::string& text, const std::string& file) {
  VtkHeader header = ReadHeader(text, file);
  // Tokens from line 4 on, keeping line numbers.
  Tokens t(text, file, header.body, 4);
  VtkBody body(file, header.v5);
  ReadTitle(body.map, std::move(header.title), file);
  if (t.Next("DATASET") != "DATASET" || t.Next("POLYDATA") != "POLYDATA") {
    throw InputError(file, t.LastLine(), "expected 'DATASET POLYDATA'");
  }
  while (!t.done()) ReadSection(t, body);
  CheckWhole(body.map, body.cell_count, file);
  return std::move(body.map);
}

WearMap ParseCsv(const std::string& text, const std::string& file) {
  std::istringstream in(text);
  std::string header;
  std::getline(in, header);
  std::vector<std::string> cols;
  {
    std::stringstream hs(header);
    std::string c;
    while (std::getline(hs, c, ',')) {
      while (!c.empty() && std::isspace(static_cast<unsigned char>(c.back()))) c.pop_back();
      while (!c.empty() && std::isspace(static_cast<unsigned char>(c.front()))) c.erase(c.begin());
      cols.push_back(c);
    }
  }
  const char* kCoords[] = {"x1", "y1", "z1", "x2", "y2", "z2", "x3", "y3", "z3"};
  std::vector<int> coord_idx;
  for (const char* k : kCoords) {
    auto it = std::find(cols.begin(), cols.end(), k);
    if (it == cols.end())
      throw InputError(file, 1, std::string("header lacks column '") + k + "' (x1,y1,z1,x2,y2,z2,x3,y3,z3,wear required)");
    coord_idx.push_back(static_cast<int>(it - cols.begin()));
  }
  auto wear_it = std::find(cols.begin(), cols.end(), "wear");
  if (wear_it == cols.end()) throw InputError(file, 1, "header lacks column 'wear'");
  std::vector<std::pair<std::string, int>> arrays;
  for (size_t i = 0; i < cols.size(); ++i) {
    if (std::find(coord_idx.begin(), coord_idx.end(), static_cast<int>(i)) == coord_idx.end() && !cols[i].empty()) {
      arrays.emplace_back(cols[i], static_cast<int>(i));
    }
  }
  WearMap map;
  std::vector<std::vector<double>> values(arrays.size());
  std::string line;
  size_t lineno = 1;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.empty() || line == "\r") continue;
    std::vector<double> v;
    std::stringstream ls(line);
    std::string cell;
    while (std::getline(ls, cell, ',')) {
      char* end = nullptr;
      const double d = std::strtod(cell.c_str(), &end);
      while (end && *end && std::isspace(static_cast<unsigned char>(*end))) ++end;
      if (end == cell.c_str() || (end && *end) || !std::isfinite(d)) {
        throw InputError(file, lineno, "column " + std::to_string(v.size() + 1) + " '" + cell + "' is not a finite number");
      }
      v.push_back(d);
    }
    if (v.size() != cols.size())
      throw InputError(file, lineno, "has " + std::to_string(v.size()) + " columns, header has " + std::to_string(cols.size()));
    const auto base = static_cast<uint32_t>(map.points.size());
    for (int p = 0; p < 3; ++p) {
      map.points.emplace_back(v[coord_idx[3 * p]], v[coord_idx[3 * p + 1]], v[coord_idx[3 * p + 2]]);
      if (map.points.back().cwiseAbs().maxCoeff() > kMaxCoordinateM)
        throw InputError(file, lineno, OutOfFrame(map.points.back()));
    }
    if (v[static_cast<size_t>(wear_it - cols.begin())] < 0) {
      throw InputError(file, lineno, NegativeWear(map.faces.size(), v[static_cast<size_t>(wear_it - cols.begin())]));
    }
    map.faces.push_back({base, base + 1, base + 2});
    for (size_t a = 0; a < arrays.size(); ++a) values[a].push_back(v[arrays[a].second]);
  }
  if (map.faces.empty()) throw InputError(file, 0, "no faces");
  for (size_t a = 0; a < arrays.size(); ++a) {
    Assign(map, arrays[a].first, Eigen::Map<Eigen::VectorXd>(values[a].data(), static_cast<Eigen::Index>(values[a].size())));
  }
  return map;
}

// Wear is a relative intensity, so its unit is free; but the map model squares and sums it over up
// to millions of faces, which must stay finite and normal, and no DEM run gives one face more than
// a trillion times the median face's wear: such a value is a corrupt export, and it would take over
// every row's scale.
constexpr double kMinWearScale = 1e-100, kMaxWearScale = 1e100, kMaxWearOverMedian = 1e12;

void CheckWearScale(const Eigen::VectorXd& wear, const std::string& file) {
  Eigen::Index top = 0;
  const double max = wear.maxCoeff(&top);
  char b[256];
  if (max < kMinWearScale || max > kMaxWearScale) {
    std::snprintf(b, sizeof b,
                  "'wear' values reach %.3g, outside %.0e..%.0e: rescale the map (it is a relative intensity, any unit "
                  "in that range scales the same)",
                  max, kMinWearScale, kMaxWearScale);
    throw InputError(file, 0, b);
  }
  std::vector<double> positive;
  positive.reserve(static_cast<size_t>(wear.size()));
  for (const double w : wear) {
    if (w > 0) positive.push_back(w);
  }
  auto mid = positive.begin() + static_cast<std::ptrdiff_t>(positive.size() / 2);
  std::nth_element(positive.begin(), mid, positive.end());
  if (max > kMaxWearOverMedian * *mid) {
    std::snprintf(b, sizeof b,
                  "face %lld's 'wear' %.3g is more than %.0e times the median face's (%.3g): a corrupt value, not a hot spot",
                  static_cast<long long>(top), max, kMaxWearOverMedian, *mid);
    throw InputError(file, 0, b);
  }
}

MapValidation Validate(WearMap& map) {
  MapValidation v;
  const auto n = static_cast<Eigen::Index>(map.face_count());
  for (Eigen::Index i = 0; i < n; ++i) {
    if (map.areas[i] <= 1e-12) ++v.degenerate_faces;
    if (map.wear[i] < 0) ++v.negative_wear_faces;
  }
  v.zero_wear_fraction = static_cast<double>((map.wear.array() == 0.0).count()) / static_cast<double>(n);
  // %f truncation: printf("%f") keeps 6 decimals, so small intensities collapse onto few values.
  size_t on_grid = 0;
  std::set<long long> distinct;
  for (Eigen::Index i = 0; i < n; ++i) {
    const double scaled = map.wear[i] * 1e6;
    if (std::abs(scaled - std::round(scaled)) < 1e-6) ++on_grid;
    distinct.insert(std::llround(scaled));
  }
  const double max_wear = map.wear.size() ? map.wear.maxCoeff() : 0.0;
  v.looks_truncated =
      n > 20 && on_grid == static_cast<size_t>(n) && max_wear < 1e-2 && distinct.size() < static_cast<size_t>(n) / 4;
  if (v.degenerate_faces) v.warnings.push_back(std::to_string(v.degenerate_faces) + " degenerate (zero-area) faces");
  if (v.negative_wear_faces) v.warnings.push_back(std::to_string(v.negative_wear_faces) + " faces with negative wear");
  if (v.zero_wear_fraction > 0.25) {
    char b[96];
    std::snprintf(b, sizeof b, "%.0f %% of faces have zero wear (short DEM run or unreached area?)", 100 * v.zero_wear_fraction);
    v.warnings.push_back(b);
  }
  if (v.looks_truncated)
    v.warnings.push_back("wear values look %f-truncated to 6 decimals: rescale the DEM output before export");
  return v;
}

}  // namespace

void WearMap::ComputeGeometry() {
  const size_t n = faces.size();
  centroids.resize(n);
  normals.resize(n);
  areas.resize(static_cast<Eigen::Index>(n));
  z.resize(static_cast<Eigen::Index>(n));
  theta_deg.resize(static_cast<Eigen::Index>(n));
  radius.resize(static_cast<Eigen::Index>(n));
  flipped_faces = 0;
  for (size_t i = 0; i < n; ++i) {
    const auto& a = points[faces[i][0]];
    const auto& b = points[faces[i][1]];
    const auto& c = points[faces[i][2]];
    const Eigen::Vector3d cross = (b - a).cross(c - a);
    const auto k = static_cast<Eigen::Index>(i);
    areas[k] = 0.5 * cross.norm();
    const Eigen::Vector3d cen = (a + b + c) / 3.0;
    centroids[i] = cen;
    Eigen::Vector3d nrm = areas[k] > 0 ? Eigen::Vector3d(cross.normalized()) : Eigen::Vector3d(0, 0, 0);
    const Eigen::Vector3d radial(cen.x(), cen.y(), 0.0);
    if (nrm.dot(radial) > 0) {  // pointing away from the axis: the liner's inner surface faces inward
      nrm = -nrm;
      ++flipped_faces;
    }
    normals[i] = nrm;
    z[k] = cen.z();
    radius[k] = std::hypot(cen.x(), cen.y());
    double th = std::atan2(cen.y(), cen.x()) * 180.0 / M_PI;
    if (th < 0) th += 360.0;
    theta_deg[k] = th;
  }
}

WearMap LoadWearMap(const std::filesystem::path& path, MapValidation* validation) {
  return ParseWearMap(ReadFile(path), path.filename().string(), validation);
}

WearMap ParseWearMap(const std::string& text, const std::string& file, MapValidation* validation) {
  std::string ext = std::filesystem::path(file).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  WearMap map;
  if (ext == ".vtk")
    map = ParseVtk(text, file);
  else if (ext == ".csv")
    map = ParseCsv(text, file);
  else
    throw InputError(file, 0, "unknown map format '" + ext + "' (expected .vtk or .csv)");
  // Coordinates beyond kMaxCoordinateM were refused, with their line, while parsing.
  const auto n = static_cast<Eigen::Index>(map.faces.size());
  for (const auto* arr : {&map.normal_stress, &map.shear_stress, &map.wear_stderr}) {
    if (arr->size() != 0 && arr->size() != n) throw InputError(file, 0, "per-face array length differs from the face count");
  }
  if (map.has_wear_stderr() && (map.wear_stderr.array() < 0).any()) {
    throw InputError(file, 0, "'wear_stderr' has negative values (a standard error is >= 0)");
  }
  if (map.wear.size() != n)
    throw InputError(file, 0, "'wear' has " + std::to_string(map.wear.size()) + " values for " + std::to_string(n) + " faces");
  if (!(map.wear.maxCoeff() > 0)) throw InputError(file, 0, "every face has zero wear: the map cannot be scaled by the sensors");
  CheckWearScale(map.wear, file);
  if (map.has_wear_stderr() && map.wear_stderr.maxCoeff() > kMaxWearScale)
    throw InputError(file, 0, "'wear_stderr' values beyond 1e+100: not on the scale of any 'wear'");
  map.ComputeGeometry();
  map.sha256 = Sha256Hex(text);
  MapValidation v = Validate(map);
  v.outward_faces_flipped = map.flipped_faces;
  if (v.outward_faces_flipped > 0 && v.outward_faces_flipped < map.face_count()) {
    v.warnings.push_back(std::to_string(v.outward_faces_flipped) + " faces were wound outward and were re-oriented inward");
  }
  if (validation) *validation = v;
  return map;
}

void WriteWearMapVtk(const std::filesystem::path& path, const WearMap& map,
                     const std::vector<std::pair<std::string, const Eigen::VectorXd*>>& cell_arrays,
                     const std::string& title_arg) {
  const auto n = map.face_count();
  if (title_arg.size() > 255 || title_arg.find_first_of("\r\n") != std::string::npos)
    throw std::invalid_argument("a VTK title is one line of at most 255 characters");
  for (const auto& [name, arr] : cell_arrays) {
    if (!arr || static_cast<size_t>(arr->size()) != n)
      throw std::invalid_argument("cell array '" + name + "' does not have one value per face");
    if (name.empty() || name.find_first_of(" \t\n") != std::string::npos)
      throw std::invalid_argument("cell array name '" + name + "' is not a VTK name");
  }
  WriteFileAtomically(path, [&](std::ostream& out) {
    out.precision(10);
    // The given title, else the map's own (a re-written map keeps e.g. its windows=K), else a default.
    std::string title = !title_arg.empty()  ? title_arg
                        : map.title.empty() ? std::string("linerwatch wear map")
                                            : map.title.substr(0, 250);
    for (char& ch : title)
      if (ch == '\n' || ch == '\r') ch = ' ';
    out << "# vtk DataFile Version 4.2\n" << title << "\nASCII\nDATASET POLYDATA\n";
    out << "POINTS " << map.points.size() << " double\n";
    for (const auto& p : map.points) out << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
    out << "POLYGONS " << n << ' ' << 4 * n << '\n';
    for (const auto& f : map.faces) out << "3 " << f[0] << ' ' << f[1] << ' ' << f[2] << '\n';
    out << "CELL_DATA " << n << '\n';
    for (const auto& [name, arr] : cell_arrays) {
      out << "SCALARS " << name << " double 1\nLOOKUP_TABLE default\n";
      for (Eigen::Index i = 0; i < arr->size(); ++i) out << (*arr)[i] << '\n';
    }
  });
}

}  // namespace lw::core
