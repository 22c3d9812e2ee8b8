// libFuzzer harness: the labelling page's edits (`POST /api/labels` and `PATCH /api/labels/ID`
// of `sightmap serve`) as cli/label_service.h takes them, on a model file with one keyframe and
// one label. The input is the request body; a ServiceError (or another sightmap::Error) is the
// right answer to a bad one, anything else (a JSON type error escaping, a crash) is a finding.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "cli/label_service.h"
#include "core/check.h"
#include "fuzz/fuzz_inputs.h"
#include "store/model.h"
#include "store/synthetic_model.h"

namespace {

struct Fixture {
  std::string path;
  int64_t label_id = 0;
  std::unique_ptr<sightmap::cli::LabelService> service;
};

Fixture& TheFixture() {
  static Fixture* fixture = [] {
    auto* made = new Fixture;
    made->path = sightmap::fuzz::ScratchDir() + "/labels.db";
    std::remove(made->path.c_str());
    {
      // Closed before the service opens it: a model has one writer at a time.
      sightmap::store::Model model = sightmap::store::Model::Open(made->path);
      sightmap::store::SyntheticKeyframeOptions options;
      options.width = 64;
      options.height = 48;
      options.num_features = 10;
      const sightmap::SessionId session = model.BeginSession({});
      model.AddKeyframe(sightmap::store::MakeSyntheticKeyframe(session, 0, options));
    }
    made->service = std::make_unique<sightmap::cli::LabelService>(
        made->path, sightmap::cli::LabelServiceOptions(), [](const sightmap::store::Model&) {});
    made->label_id =
        made->service->AddPoint({{"name", "lamp"}, {"keyframe", 1}, {"pixel", {10, 10}}})
            .at("label")
            .at("id")
            .get<int64_t>();
    return made;
  }();
  return *fixture;
}

// Puts the model back as the fixture made it: the one label, named and typed as before.
void Restore(Fixture& fixture) {
  sightmap::store::Model model = sightmap::store::Model::Open(fixture.path);
  for (const sightmap::store::LabelRecord& label : model.Labels()) {
    if (label.id.value() != fixture.label_id) model.DeleteLabel(label.id);
  }
  for (sightmap::store::LabelRecord label : model.Labels()) {
    label.name = "lamp";
    label.type = "appliance";
    label.points.resize(1);
    model.UpdateLabel(label);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Fixture& fixture = TheFixture();
  const nlohmann::json request =
      nlohmann::json::parse(data, data + size, nullptr, /*allow_exceptions=*/false);
  if (request.is_discarded()) return 0;  // the server answers 400 before the service sees it
  try {
    fixture.service->AddPoint(request);
  } catch (const sightmap::Error&) {
  }
  try {
    fixture.service->Edit(fixture.label_id, request);
  } catch (const sightmap::Error&) {
  }
  Restore(fixture);
  return 0;
}
