#include "core/optim/results_io.h"

#include <algorithm>
#include <fstream>

#include "core/error.h"
#include "core/image/image.h"

namespace invr {

std::vector<std::string> writeParameters(const std::filesystem::path& dir, const ParameterRegistry& params,
                                         const std::vector<float>& theta) {
  std::vector<std::string> files{"parameters.json"};
  std::ofstream js(dir / "parameters.json");
  if (!js) throw InputError("cannot write '" + (dir / "parameters.json").string() + "'");
  js << "{\n";
  for (size_t i = 0; i < params.slots().size(); ++i) {
    const ParameterSlot& s = params.slots()[i];
    js << "  \"" << s.name << "\": ";
    if (s.width > 0) {
      std::string file = s.name;
      std::replace(file.begin(), file.end(), '/', '_');
      file += ".exr";
      Image im(s.width, s.height, 3);
      for (int y = 0; y < s.height; ++y)
        for (int x = 0; x < s.width; ++x)
          for (int c = 0; c < 3; ++c)
            im.at(x, y, c) = theta[s.offset + size_t((y * s.width + x) * s.channels + std::min(c, s.channels - 1))];
      writeImage(dir / file, im);
      files.push_back(file);
      js << "{\"texture\": \"" << file << "\", \"width\": " << s.width << ", \"height\": " << s.height << "}";
    } else {
      js << "[";
      for (uint32_t k = 0; k < s.size; ++k) js << (k ? ", " : "") << theta[s.offset + k];
      js << "]";
    }
    js << (i + 1 < params.slots().size() ? ",\n" : "\n");
  }
  js << "}\n";
  return files;
}

}  // namespace invr
