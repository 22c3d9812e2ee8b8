#include "cli/web_assets.h"

#include <regex>
#include <string>

#include <gtest/gtest.h>

namespace sightmap::cli {
namespace {

TEST(WebAssets, PagesAreServedAtTheirRoutesWithTheirTypes) {
  const std::optional<WebAsset> phone = FindWebAsset("/");
  ASSERT_TRUE(phone);
  EXPECT_EQ(phone->content_type, "text/html; charset=utf-8");
  EXPECT_NE(phone->bytes.find("capture=\"environment\""), std::string_view::npos);
  const std::optional<WebAsset> label = FindWebAsset("/label");
  ASSERT_TRUE(label);
  EXPECT_NE(label->bytes.find("/static/label.js"), std::string_view::npos);
  ASSERT_TRUE(FindWebAsset("/static/phone.js"));
  EXPECT_EQ(FindWebAsset("/static/phone.js")->content_type, "text/javascript; charset=utf-8");
  EXPECT_EQ(FindWebAsset("/static/sightmap.css")->content_type, "text/css; charset=utf-8");
  EXPECT_FALSE(FindWebAsset("/static/label.html")) << "pages only at their routes";
  EXPECT_FALSE(FindWebAsset("/static/none.js"));
  ASSERT_TRUE(FindWebAsset("/static/marks.js"));
  for (const char* page : {"/", "/label"}) {
    EXPECT_NE(FindWebAsset(page)->bytes.find("/static/marks.js"), std::string_view::npos) << page;
  }
  EXPECT_FALSE(FindWebAsset("/nowhere"));
}

// Works offline: every script and style sheet a page names is one the server carries, and none
// comes from another host.
TEST(WebAssets, EveryReferenceOfAPageIsEmbedded) {
  const std::regex reference(R"((?:src|href)="([^"]+)\")");
  for (const char* route : {"/", "/label"}) {
    const std::string page(FindWebAsset(route)->bytes);
    int checked = 0;
    for (std::sregex_iterator it(page.begin(), page.end(), reference), end; it != end; ++it) {
      const std::string target = (*it)[1];
      EXPECT_EQ(target.find("//"), std::string::npos) << route << " fetches " << target;
      EXPECT_TRUE(FindWebAsset(target)) << route << " names " << target;
      ++checked;
    }
    EXPECT_GE(checked, 3) << route;
  }
}

}  // namespace
}  // namespace sightmap::cli
