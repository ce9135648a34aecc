// SPDX-License-Identifier: Apache-2.0
// Small text files the farm reads whole: tokens, token lists, PEM certificates and keys.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include "farm/farm_error.h"

namespace tessera::farm {

// The file's bytes; throws FarmError "cannot read <what> <path>" ("cannot read <path>"
// when `what` is empty).
std::string read_text_file(const std::filesystem::path& path, std::string_view what = {});

// `s` without leading and trailing blanks (space, tab, CR, LF).
std::string trim_blanks(std::string_view s);

}  // namespace tessera::farm
