// SPDX-License-Identifier: Apache-2.0
// A small HTTP client on libcurl for the daemon's tests: one request at a
// time, any method, headers, a body, the status, the answer's headers
// (names in lower case) and body. Paths are sent as given (no dot-segment
// squashing), so tests can send "..", "%2e%2e" and the like.
#pragma once

#include <curl/curl.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace cylscan::test {

struct HttpResponse {
  long status = 0;  // 0: no answer (curl_error says why)
  std::string body;
  std::map<std::string, std::string> headers;  // lower-case names; last value wins
  std::string curl_error;

  std::string header(const std::string& name) const {
    const auto it = headers.find(name);
    return it == headers.end() ? std::string() : it->second;
  }
  // The body as JSON; a JSON null when it is not JSON.
  nlohmann::json json() const {
    nlohmann::json j = nlohmann::json::parse(body, nullptr, /*allow_exceptions=*/false);
    // parse() without exceptions gives a "discarded" value, on which value()
    // and the like throw; a null is what the callers test for.
    return j.is_discarded() ? nlohmann::json() : j;
  }
  // The "error" of a JSON error body, or "" when there is none.
  std::string error() const {
    const auto j = json();
    if (j.is_object() && j.contains("error") && j["error"].is_string()) return j["error"];
    return {};
  }
  // For failure messages.
  std::string describe() const {
    std::string s = "HTTP " + std::to_string(status);
    if (!curl_error.empty()) s += " (curl: " + curl_error + ")";
    return s + ": " + body.substr(0, 500);
  }
};

class HttpClient {
 public:
  using Headers = std::vector<std::string>;  // "Name: value"

  explicit HttpClient(std::string base_url) : base_(std::move(base_url)) {
    static const bool initialised = curl_global_init(CURL_GLOBAL_DEFAULT) == CURLE_OK;
    if (!initialised) throw std::runtime_error("curl_global_init failed");
  }

  // Headers sent with every request (e.g. the bearer token).
  void setDefaultHeaders(Headers headers) { defaults_ = std::move(headers); }
  const std::string& baseUrl() const { return base_; }

  HttpResponse request(const std::string& method, const std::string& path,
                       const std::string& body = {}, const Headers& headers = {},
                       std::chrono::milliseconds timeout = std::chrono::seconds(30)) const {
    std::unique_ptr<CURL, decltype(&curl_easy_cleanup)> curl(curl_easy_init(), curl_easy_cleanup);
    if (!curl) throw std::runtime_error("curl_easy_init failed");
    CURL* c = curl.get();
    HttpResponse response;
    const std::string url = base_ + path;
    curl_easy_setopt(c, CURLOPT_URL, url.c_str());
    curl_easy_setopt(c, CURLOPT_PATH_AS_IS, 1L);
    curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
    curl_easy_setopt(c, CURLOPT_TIMEOUT_MS, static_cast<long>(timeout.count()));
    curl_easy_setopt(c, CURLOPT_CONNECTTIMEOUT_MS, 5000L);
    curl_easy_setopt(c, CURLOPT_PROXY, "");  // never a proxy for 127.0.0.1
    if (method == "HEAD") {
      curl_easy_setopt(c, CURLOPT_NOBODY, 1L);
    } else {
      curl_easy_setopt(c, CURLOPT_CUSTOMREQUEST, method.c_str());
    }
    if (!body.empty() || method == "POST" || method == "PUT") {
      curl_easy_setopt(c, CURLOPT_POSTFIELDS, body.data());
      curl_easy_setopt(c, CURLOPT_POSTFIELDSIZE_LARGE, static_cast<curl_off_t>(body.size()));
    }
    curl_slist* list = nullptr;
    Headers all = defaults_;
    all.insert(all.end(), headers.begin(), headers.end());
    // No "Expect: 100-continue" unless a test asks for it.
    if (std::none_of(all.begin(), all.end(),
                     [](const std::string& h) { return h.rfind("Expect:", 0) == 0; })) {
      all.push_back("Expect:");
    }
    for (const auto& h : all)
      list = curl_slist_append(list, h.c_str());
    std::unique_ptr<curl_slist, decltype(&curl_slist_free_all)> list_owner(list,
                                                                           curl_slist_free_all);
    curl_easy_setopt(c, CURLOPT_HTTPHEADER, list);
    curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, &HttpClient::onBody);
    curl_easy_setopt(c, CURLOPT_WRITEDATA, &response);
    curl_easy_setopt(c, CURLOPT_HEADERFUNCTION, &HttpClient::onHeader);
    curl_easy_setopt(c, CURLOPT_HEADERDATA, &response);
    const CURLcode rc = curl_easy_perform(c);
    if (rc != CURLE_OK) response.curl_error = curl_easy_strerror(rc);
    curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &response.status);
    return response;
  }

  // A streamed GET (e.g. server-sent events): `on_data` gets each chunk as it
  // comes (and "" now and then while nothing comes) and returns false to stop
  // (the answer then has a curl_error); `timeout` bounds the whole stream.
  HttpResponse stream(const std::string& path,
                      const std::function<bool(const std::string&)>& on_data,
                      std::chrono::milliseconds timeout, const Headers& headers = {}) const {
    std::unique_ptr<CURL, decltype(&curl_easy_cleanup)> curl(curl_easy_init(), curl_easy_cleanup);
    if (!curl) throw std::runtime_error("curl_easy_init failed");
    CURL* c = curl.get();
    struct Sink {
      HttpResponse response;
      const std::function<bool(const std::string&)>* on_data;
    } sink{HttpResponse{}, &on_data};
    const std::string url = base_ + path;
    curl_easy_setopt(c, CURLOPT_URL, url.c_str());
    curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
    curl_easy_setopt(c, CURLOPT_TIMEOUT_MS, static_cast<long>(timeout.count()));
    curl_easy_setopt(c, CURLOPT_PROXY, "");
    curl_slist* list = nullptr;
    Headers all = defaults_;
    all.insert(all.end(), headers.begin(), headers.end());
    for (const auto& h : all)
      list = curl_slist_append(list, h.c_str());
    std::unique_ptr<curl_slist, decltype(&curl_slist_free_all)> list_owner(list,
                                                                           curl_slist_free_all);
    curl_easy_setopt(c, CURLOPT_HTTPHEADER, list);
    curl_easy_setopt(c, CURLOPT_HEADERFUNCTION, &HttpClient::onHeader);
    curl_easy_setopt(c, CURLOPT_HEADERDATA, &sink.response);
    curl_easy_setopt(
        c, CURLOPT_WRITEFUNCTION, +[](char* data, std::size_t size, std::size_t n, void* user) {
          auto* s = static_cast<Sink*>(user);
          const std::string chunk(data, size * n);
          s->response.body += chunk;
          return (*s->on_data)(chunk) ? size * n : std::size_t{0};
        });
    curl_easy_setopt(c, CURLOPT_WRITEDATA, &sink);
    // Called about once a second even when nothing comes: on_data("") may stop.
    curl_easy_setopt(c, CURLOPT_NOPROGRESS, 0L);
    curl_easy_setopt(
        c, CURLOPT_XFERINFOFUNCTION,
        +[](void* user, curl_off_t, curl_off_t, curl_off_t, curl_off_t) {
          return (*static_cast<Sink*>(user)->on_data)(std::string()) ? 0 : 1;
        });
    curl_easy_setopt(c, CURLOPT_XFERINFODATA, &sink);
    const CURLcode rc = curl_easy_perform(c);
    if (rc != CURLE_OK) sink.response.curl_error = curl_easy_strerror(rc);
    curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &sink.response.status);
    return sink.response;
  }

  HttpResponse get(const std::string& path, const Headers& headers = {}) const {
    return request("GET", path, {}, headers);
  }
  HttpResponse post(const std::string& path, const std::string& body = {},
                    const Headers& headers = {}) const {
    return request("POST", path, body, headers);
  }
  HttpResponse postJson(const std::string& path, const nlohmann::json& body,
                        const Headers& headers = {}) const {
    Headers h = headers;
    h.push_back("Content-Type: application/json");
    return request("POST", path, body.dump(), h);
  }
  HttpResponse put(const std::string& path, const std::string& body,
                   const Headers& headers = {}) const {
    Headers h = headers;
    h.push_back("Content-Type: application/octet-stream");
    return request("PUT", path, body, h);
  }
  HttpResponse del(const std::string& path, const Headers& headers = {}) const {
    return request("DELETE", path, {}, headers);
  }

 private:
  static std::size_t onBody(char* data, std::size_t size, std::size_t n, void* user) {
    static_cast<HttpResponse*>(user)->body.append(data, size * n);
    return size * n;
  }
  static std::size_t onHeader(char* data, std::size_t size, std::size_t n, void* user) {
    auto* response = static_cast<HttpResponse*>(user);
    const std::string line(data, size * n);
    const auto colon = line.find(':');
    if (line.rfind("HTTP/", 0) == 0) {
      response->headers.clear();  // a new status line (after 100 Continue)
    } else if (colon != std::string::npos) {
      std::string name = line.substr(0, colon);
      std::transform(name.begin(), name.end(), name.begin(),
                     [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
      std::string value = line.substr(colon + 1);
      const auto first = value.find_first_not_of(" \t");
      const auto last = value.find_last_not_of(" \t\r\n");
      value = first == std::string::npos ? std::string() : value.substr(first, last - first + 1);
      response->headers[name] = value;
    }
    return size * n;
  }

  std::string base_;
  Headers defaults_;
};

}  // namespace cylscan::test
