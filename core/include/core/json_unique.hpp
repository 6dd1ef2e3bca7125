#pragma once
/// JSON files an operator writes (crusher.json, the programs' config files) are parsed by this one
/// rule: a key given twice in one object is refused. nlohmann keeps the last value silently, so a
/// second "site" or "thickness_new_mm" further down a file would win unseen.
#include <nlohmann/json.hpp>

#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace lw::core {

/// Thrown for a key repeated in one object; what() names the key and the object it is in.
struct DuplicateJsonKey : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// nlohmann::json::parse(input), refusing duplicate keys (DuplicateJsonKey). Its other exceptions
/// (parse_error, out_of_range) pass through unchanged.
template <class Input>
nlohmann::json ParseJsonUniqueKeys(Input&& input) {
  using json = nlohmann::json;
  struct Object {
    std::string name;
    std::set<std::string> keys;
  };
  std::vector<Object> open;  // the objects being parsed, innermost last
  std::string last_key;      // names the next object opened under it
  return json::parse(std::forward<Input>(input), [&](int, json::parse_event_t event, json& parsed) {
    if (event == json::parse_event_t::object_start) {
      open.push_back({open.empty() ? "the top level" : "\"" + last_key + "\"", {}});
    } else if (event == json::parse_event_t::object_end) {
      if (!open.empty()) open.pop_back();
    } else if (event == json::parse_event_t::key && parsed.is_string()) {
      last_key = parsed.get<std::string>();
      if (!open.empty() && !open.back().keys.insert(last_key).second)
        throw DuplicateJsonKey("key \"" + last_key + "\" appears twice in " + open.back().name);
    }
    return true;
  });
}

}  // namespace lw::core
