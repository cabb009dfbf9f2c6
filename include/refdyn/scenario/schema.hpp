#pragma once
/// The scenario file's sections, each declared once: per section one table of its keys (name,
/// type as written, whether it is required, default, unit, one line of documentation, and the
/// words of a choice). The reader's unknown-key checks (SpecReader::keys), its choice lists,
/// the key tables of docs/scenario.md (`refdyn kinds --sections`, checked by
/// tests/registry_test.cpp) and the defaults' agreement with the option structs
/// (tests/registry_test.cpp) come from these tables; src/scenario/schema.cpp holds them.
///
/// The entries of the registries (constraint kinds, force elements, controllers) declare
/// their own keys (scenario/registry.hpp, KeyDoc); this file declares the fixed sections.

#include <string>
#include <string_view>
#include <vector>

namespace refdyn::schema {

/// One key of a section.
struct Key {
  std::string name;
  std::string type;          ///< as written: "number", "whole number", "list of joints", "mapping", …
  std::string required;      ///< "" optional; else "yes" or when ("for track", …)
  std::string default_text;  ///< what an absent key means ("" none: the doc says)
  std::string unit;          ///< of a number: "s", "1/s", …; "" none (dimensionless or not a number)
  std::string doc;           ///< one line
  std::vector<std::string> choices;  ///< the words a choice key accepts, in order (else empty)
};

/// One section: its path as keys are named in messages ("" the file's top level,
/// "integrator", "optimize.tolerance"; "[]" an entry of a list: "experiments[]",
/// "optimize.variables[]").
struct Section {
  std::string path;
  std::string doc;
  std::vector<Key> keys;
};

/// Every declared section, in the order of docs/scenario.md.
const std::vector<Section>& sections();
/// The section declared at `path`; throws std::logic_error if none is (a programming error).
const Section& section(std::string_view path);
/// Its keys' names, in order: the allowed keys of SpecReader::keys.
const std::vector<std::string>& keys(std::string_view path);
/// One declared key; throws std::logic_error if it is not declared.
const Key& key(std::string_view path, std::string_view name);
/// The words of a choice key, in order (SpecReader::choice).
const std::vector<std::string>& choices(std::string_view path, std::string_view name);

/// The key tables of docs/scenario.md, one per section (`refdyn kinds --sections`).
std::string markdown();

}  // namespace refdyn::schema
