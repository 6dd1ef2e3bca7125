#include "server/query.hpp"

#include <charconv>
#include <stdexcept>

#include "core/time.hpp"
#include "server/store.hpp"

namespace lw::server {
const std::string* FindParam(const QueryParams& params, const char* name) {
  const auto it = params.lower_bound(name);
  return it == params.end() || it->first != name ? nullptr : &it->second;
}

bool TimeParam(const QueryParams& params, const char* name, int64_t* out, std::string* error) {
  const std::string* v = FindParam(params, name);
  if (!v) return true;
  const auto t = core::ParseIsoTime(*v);
  if (!t) {
    *error = std::string(name) + "='" + *v + "' is not an ISO-8601 time (YYYY-MM-DDTHH:MM:SSZ)";
    return false;
  }
  *out = t->time_since_epoch().count();
  return true;
}

bool WholeNumberParam(const QueryParams& params, const char* name, int min, int max, int* out, std::string* error) {
  const std::string* v = FindParam(params, name);
  if (!v) return true;
  const std::string range = "[" + std::to_string(min) + ", " + std::to_string(max) + "]";
  int x = 0;
  const char* end = v->data() + v->size();
  const auto [ptr, ec] = std::from_chars(v->data(), end, x);
  if (v->empty() || ptr != end || (ec != std::errc() && ec != std::errc::result_out_of_range)) {
    *error = std::string(name) + "='" + *v + "' is not a whole number in " + range;
    return false;
  }
  if (ec == std::errc::result_out_of_range || x < min || x > max) {
    *error = std::string(name) + "=" + *v + " must be in " + range;
    return false;
  }
  *out = x;
  return true;
}

std::optional<ReadingsQuery> ParseReadingsQuery(const QueryParams& params, std::string* error) {
  ReadingsQuery q;
  if (!TimeParam(params, "from", &q.from_s, error) || !TimeParam(params, "to", &q.to_s, error)) return std::nullopt;
  if (!WholeNumberParam(params, "limit", 1, 5000, &q.limit, error)) return std::nullopt;
  if (const std::string* v = FindParam(params, "cursor")) q.cursor = *v;
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
