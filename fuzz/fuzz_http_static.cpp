// SPDX-License-Identifier: Apache-2.0
// Static file confinement: a request path goes through the router and, when
// it is a static file, openStaticFile under a web root. The root holds a few
// files, a symlink to one of them and a symlink (and a "../" neighbour) that
// lead outside it; whatever the path, a file outside the root must never be
// opened. The raw input is also given to openStaticFile directly, without
// the router's checks in front.
#include <sys/stat.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <set>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "firmware/http/files.hpp"
#include "firmware/http/router.hpp"
#include "fuzz/fuzz_support.hpp"

namespace {

namespace fs = std::filesystem;
using Inode = std::pair<dev_t, ino_t>;

struct WebRoot {
  fs::path root;
  std::set<Inode> inside;  // the regular files under root
};

Inode inodeOf(int fd) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw std::runtime_error("fstat failed");
  return {st.st_dev, st.st_ino};
}

const WebRoot& webRoot() {
  static const WebRoot web = [] {
    WebRoot w;
    const fs::path top = cylscan::fuzz::scratchDir();
    w.root = top / "web";
    fs::create_directories(w.root / "assets" / "img");
    cylscan::fuzz::writeFile(top / "secret.txt", "outside the root\n");
    cylscan::fuzz::writeFile(top / "web-secret.txt", "beside the root\n");
    cylscan::fuzz::writeFile(w.root / "index.html", "<!doctype html>\n");
    cylscan::fuzz::writeFile(w.root / "assets" / "app.js", "console.log(1);\n");
    cylscan::fuzz::writeFile(w.root / "assets" / "img" / "logo.svg", "<svg/>\n");
    fs::create_symlink("../secret.txt", w.root / "escape.txt");
    fs::create_symlink("../../web-secret.txt", w.root / "assets" / "up.txt");
    fs::create_directory_symlink("..", w.root / "parent");
    fs::create_symlink("index.html", w.root / "home.html");
    for (const auto& entry : fs::recursive_directory_iterator(w.root)) {
      if (entry.is_symlink() || !entry.is_regular_file()) continue;
      struct stat st {};
      if (::stat(entry.path().c_str(), &st) == 0) w.inside.insert({st.st_dev, st.st_ino});
    }
    return w;
  }();
  return web;
}

void checkConfined(const WebRoot& web, const std::optional<cylscan::firmware::http::OpenFile>& f) {
  if (f && web.inside.count(inodeOf(f->fd())) == 0)
    throw std::logic_error("openStaticFile opened a file outside the web root");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace http = cylscan::firmware::http;
  const WebRoot& web = webRoot();
  const std::string_view input = cylscan::fuzz::asText(data, size);
  if (input.find('\0') != std::string_view::npos) return 0;  // no C path holds a NUL
  const http::Route r = http::route("GET", input);
  if (r.status == 0 && r.endpoint == http::Endpoint::Static)
    checkConfined(web, http::openStaticFile(web.root, r.name));
  checkConfined(web, http::openStaticFile(web.root, input));
  return 0;
}
