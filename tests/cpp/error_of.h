#pragma once
// The message of the std::invalid_argument a call throws, or "no error": lets a test assert on
// an error's wording with gmock matchers.
#include <stdexcept>
#include <string>

namespace aos::test_util {

template <typename Call>
std::string ErrorOf(Call&& call) {
  try {
    call();
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "no error";
}

}  // namespace aos::test_util
