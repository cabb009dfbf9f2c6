#pragma once
/// Scenario files (YAML) → ScenarioSpec (spec.hpp): the mapping from text to plain structs.
/// This layer checks the structure (known keys at every level, each key once, one YAML
/// document, the registries' keys for constraints, forces and controllers) and reads the URDF a
/// model names; it evaluates no numbers and builds nothing. build_problem (problem.hpp) does
/// the rest. Errors name the file, the line and the key, e.g.
///   arm.yaml:12: model.dh.joints[1].mass: expected a number >= 0, got -3
/// docs/scenario.md documents every key.

#include "refdyn/scenario/problem.hpp"
#include "refdyn/scenario/spec.hpp"

#include <cstddef>
#include <memory>
#include <string>

namespace refdyn::io {

/// Largest scenario or URDF file read (bytes); larger files are rejected before parsing.
inline constexpr std::size_t kDefaultMaxInputBytes = 16u << 20;

/// Reads a whole text file of at most max_bytes (a regular file; no devices, no folders).
/// Throws Error "WHAT 'path': …" with the reason.
std::string read_text_file(const std::string& path, const std::string& what,
                           std::size_t max_bytes = kDefaultMaxInputBytes);

/// Parses scenario text; `source_name` is used in messages and to resolve relative paths.
ScenarioSpec parse_scenario(const std::string& yaml, const std::string& source_name,
                            std::size_t max_input_bytes = kDefaultMaxInputBytes);
/// Reads and parses a scenario file.
/// The file as written (YAML → SpecValue, every value with its line and column), without
/// reading any section: what parse_scenario keeps as ScenarioSpec::root.
SpecValue parse_yaml_tree(const std::string& yaml, const std::string& source_name);
ScenarioSpec load_scenario(const std::string& path, std::size_t max_input_bytes = kDefaultMaxInputBytes);

/// load_scenario + build_problem (the base scenario; a `variants:` section is checked too, see
/// io/variants.hpp for running it).
std::unique_ptr<Problem> load_problem(const std::string& path, std::size_t max_input_bytes = kDefaultMaxInputBytes);
/// parse_scenario + build_problem.
std::unique_ptr<Problem> parse_problem(const std::string& yaml, const std::string& source_name);

}  // namespace refdyn::io
