// The scenario reader's refusals, for tests of its messages.
#pragma once

#include "app/scenario.hpp"

#include <lgvi/error.hpp>

#include <gtest/gtest.h>

#include <exception>
#include <string>
#include <typeinfo>

namespace lgvi::test {

/// The message of the InvalidInput that parsing `text` (named `name`)
/// throws; fails the test if it throws nothing or something else.
inline std::string parse_error(const std::string& text, const std::string& name) {
  try {
    lgvi::app::parse_scenario(text, name);
  } catch (const InvalidInput& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "threw a " << typeid(e).name() << " that is not an InvalidInput: " << e.what();
    return {};
  }
  ADD_FAILURE() << "parsed without error:\n" << text;
  return {};
}

}  // namespace lgvi::test
