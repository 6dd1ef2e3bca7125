#include "server/query.hpp"

#include <stdexcept>

#include "core/time.hpp"
#include "server/store.hpp"

namespace lw::server {
namespace {

const std::string* Param(const QueryParams& params, const char* name) {
  const auto it = params.find(name);
  return it == params.end() ? nullptr : &it->second;
}

bool TimeParam(const QueryParams& params, const char* name, int64_t* out, std::string* error) {
  const std::string* v = Param(params, name);
  if (!v) return true;
  const auto t = core::ParseIsoTime(*v);
  if (!t) {
    *error = std::string(name) + "='" + *v + "' is not an ISO-8601 time (YYYY-MM-DDTHH:MM:SSZ)";
    return false;
  }
  *out = t->time_since_epoch().count();
  return true;
}

}  // namespace

std::optional<ReadingsQuery> ParseReadingsQuery(const QueryParams& params, std::string* error) {
  ReadingsQuery q;
  if (!TimeParam(params, "from", &q.from_s, error) || !TimeParam(params, "to", &q.to_s, error)) return std::nullopt;
  if (const std::string* v = Param(params, "limit")) {
    try {
      size_t used = 0;
      q.limit = std::stoi(*v, &used);
      if (used != v->size()) throw std::invalid_argument("");
    } catch (const std::exception&) {
      *error = "limit='" + *v + "' is not a whole number";
      return std::nullopt;
    }
    if (q.limit < 1 || q.limit > 5000) {
      *error = "limit must be in [1, 5000]";
      return std::nullopt;
    }
  }
  if (const std::string* v = Param(params, "cursor")) q.cursor = *v;
  if (!q.cursor.empty()) {
    try {
      int64_t t = 0, s = 0;
      ParseCursor(q.cursor, &t, &s);
    } catch (const std::invalid_argument& e) {
      *error = e.what();
      return std::nullopt;
    }
  }
  return q;
}

}  // namespace lw::server
