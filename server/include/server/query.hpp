#pragma once
/// Query parameters of the REST API, parsed apart from the HTTP layer (docs/server.md).
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>

namespace lw::server {

/// Decoded query parameters, name -> value (cpp-httplib's Params); the first value of a name counts.
using QueryParams = std::multimap<std::string, std::string>;

/// The first value of query parameter `name`; nullptr when it is absent.
const std::string* FindParam(const QueryParams& params, const char* name);

/// Query parameter `name` as a whole number in [min, max]; `*out` is left alone when it is absent.
/// Returns false and sets `*error` (the 400 message: the parameter, its value, the range) otherwise.
bool WholeNumberParam(const QueryParams& params, const char* name, int min, int max, int* out, std::string* error);

/// Query parameter `name` as an ISO-8601 time (core::ParseIsoTime), unix seconds; `*out` is left
/// alone when it is absent. Returns false and sets `*error` (the 400 message, naming the parameter
/// and its value) when it is not a time.
bool TimeParam(const QueryParams& params, const char* name, int64_t* out, std::string* error);

/// GET /api/v1/crushers/{id}/sensors/{sensor}/readings?from=&to=&limit=&cursor=
struct ReadingsQuery {
  int64_t from_s = std::numeric_limits<int64_t>::min();
  int64_t to_s = std::numeric_limits<int64_t>::max();
  int limit = 500;
  std::string cursor;  ///< empty: the first page; otherwise checked with ParseCursor
};

/// `from`/`to` ISO-8601 times, `limit` a whole number in [1, 5000], `cursor` one this server issued.
/// Returns nullopt and sets `*error` (the 400 message, naming the parameter) on a malformed one.
std::optional<ReadingsQuery> ParseReadingsQuery(const QueryParams& params, std::string* error);

}  // namespace lw::server
