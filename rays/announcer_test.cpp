// SPDX-License-Identifier: Apache-2.0
// The address tessera-rays announces: --advertise as given or completed with the bound port, else
// the --listen host; a wildcard --listen without --advertise is refused, naming the flag.
#include "announcer.h"

#include <gtest/gtest.h>

namespace tessera::rayserver {
namespace {

TEST(AdvertisedAddress, ListenHostWithTheBoundPort) {
  EXPECT_EQ(advertised_address("127.0.0.1:0", "", 40001), "127.0.0.1:40001");
  EXPECT_EQ(advertised_address("render7.lan:7879", "", 7879), "render7.lan:7879");
  EXPECT_EQ(advertised_address("[::1]:0", "", 40001), "[::1]:40001");
}

TEST(AdvertisedAddress, AdvertiseAsGivenOrWithTheBoundPort) {
  EXPECT_EQ(advertised_address("0.0.0.0:0", "rays.example.com", 40001), "rays.example.com:40001");
  EXPECT_EQ(advertised_address("0.0.0.0:7879", "10.1.2.3:443", 7879), "10.1.2.3:443");  // behind a proxy
  EXPECT_EQ(advertised_address("[::]:0", "[2001:db8::7]", 40001), "[2001:db8::7]:40001");
  EXPECT_EQ(advertised_address("[::]:0", "2001:db8::7", 40001), "[2001:db8::7]:40001");
  EXPECT_EQ(advertised_address("[::]:0", "[2001:db8::7]:9000", 40001), "[2001:db8::7]:9000");
}

TEST(AdvertisedAddress, WildcardListenNeedsAdvertise) {
  for (const char* listen : {"0.0.0.0:7879", "[::]:7879", ":7879"}) {
    try {
      advertised_address(listen, "", 7879);
      ADD_FAILURE() << listen << " was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("--advertise"), std::string::npos) << e.what();
    }
  }
}

TEST(ServerId, SixteenHexDigitsAndFresh) {
  const std::string a = new_server_id(), b = new_server_id();
  EXPECT_EQ(a.size(), 16u);
  EXPECT_EQ(a.find_first_not_of("0123456789abcdef"), std::string::npos) << a;
  EXPECT_NE(a, b);
}

}  // namespace
}  // namespace tessera::rayserver
