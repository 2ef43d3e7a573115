#include "core/digest.h"

#include <gtest/gtest.h>

#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

std::string hash_str(const std::string& s) { return ms::sha256_hex(s.data(), s.size()); }

TEST(Sha256, EmptyString) {
  EXPECT_EQ(hash_str(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(ms::sha256_hex(nullptr, 0), hash_str(""));
  ms::Sha256 h;
  EXPECT_EQ(h.hex_digest(), hash_str(""));
}

TEST(Sha256, Abc) {
  EXPECT_EQ(hash_str("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

TEST(Sha256, TwoBlockMessage448Bits) {
  // FIPS 180-2 / NIST 448-bit (56-byte) message: padding spills into a second block.
  const std::string msg = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
  ASSERT_EQ(msg.size() * 8, 448u);
  EXPECT_EQ(hash_str(msg), "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

TEST(Sha256, Message896Bits) {
  const std::string msg =
      "abcdefghbcdefghicdefghijdefghijkefghijklfghijklmghijklmnhijklmnoijklmnopjklmnopqklmnopqrlmn"
      "opqrsmnopqrstnopqrstu";
  ASSERT_EQ(msg.size() * 8, 896u);
  EXPECT_EQ(hash_str(msg), "cf5b16a778af8380036ce59e7b0492370b249b11e8f07a51afac45037afee9d1");
}

TEST(Sha256, MillionAInUnevenChunks) {
  const std::string expected = "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0";
  const std::string block(1000000, 'a');
  EXPECT_EQ(hash_str(block), expected);

  ms::Sha256 h;
  size_t pos = 0;
  size_t step = 1;
  while (pos < block.size()) {
    const size_t n = std::min(step, block.size() - pos);
    h.update(block.data() + pos, n);
    pos += n;
    step = step * 7 % 193 + 1;  // 1..193, crosses block boundaries irregularly
  }
  EXPECT_EQ(h.hex_digest(), expected);
}

TEST(Sha256, ChunkedEqualsOneShotForRandomData) {
  std::mt19937 rng(12345);
  std::uniform_int_distribution<int> byte(0, 255);
  for (size_t len : {0u, 1u, 55u, 56u, 63u, 64u, 65u, 119u, 120u, 128u, 1000u, 4097u}) {
    std::vector<unsigned char> data(len);
    for (auto& b : data) b = static_cast<unsigned char>(byte(rng));
    const std::string one_shot = ms::sha256_hex(data.data(), data.size());
    std::uniform_int_distribution<size_t> chunk(0, 70);
    ms::Sha256 h;
    size_t pos = 0;
    while (pos < len) {
      const size_t n = std::min(chunk(rng), len - pos);
      h.update(data.data() + pos, n);
      pos += n;
    }
    EXPECT_EQ(h.hex_digest(), one_shot) << "len=" << len;
  }
}

TEST(Sha256, DigestIsStableAndUpdateAfterFinaliseThrows) {
  ms::Sha256 h;
  h.update("abc", 3);
  const std::string d = h.hex_digest();
  EXPECT_EQ(h.hex_digest(), d);
  EXPECT_THROW(h.update("x", 1), std::logic_error);
}

}  // namespace
