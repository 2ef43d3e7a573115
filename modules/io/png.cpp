#include "io/png.h"

#include <itkImage.h>
#include <itkImageFileWriter.h>
#include <itkPNGImageIO.h>
#include <itkRGBPixel.h>

#include <algorithm>

#include "core/error.h"

namespace ms::io {

void write_png(const std::string& path, const std::vector<std::uint8_t>& pixels, int width, int height, int channels) {
  if (width <= 0 || height <= 0 || (channels != 1 && channels != 3) ||
      pixels.size() != static_cast<std::size_t>(width) * height * channels)
    throw Error(ExitCode::Internal, path + ": write_png: pixel buffer does not match " + std::to_string(width) + " x " +
                                        std::to_string(height) + " x " + std::to_string(channels));
  auto write = [&](auto img) {
    using ImageT = typename decltype(img)::ObjectType;
    typename ImageT::RegionType region;
    region.SetSize({static_cast<itk::SizeValueType>(width), static_cast<itk::SizeValueType>(height)});
    img->SetRegions(region);
    img->Allocate();
    auto* buf = img->GetBufferPointer();
    if constexpr (std::is_same_v<typename ImageT::PixelType, unsigned char>) {
      std::copy(pixels.begin(), pixels.end(), buf);
    } else {
      for (std::size_t i = 0; i < static_cast<std::size_t>(width) * height; ++i)
        for (int c = 0; c < 3; ++c) buf[i][c] = pixels[3 * i + c];
    }
    auto writer = itk::ImageFileWriter<ImageT>::New();
    writer->SetImageIO(itk::PNGImageIO::New());
    writer->SetFileName(path);
    writer->SetInput(img);
    try {
      writer->Update();
    } catch (const itk::ExceptionObject& e) {
      throw Error(ExitCode::OutputFailed, path + ": cannot write PNG");
    }
  };
  if (channels == 1)
    write(itk::Image<unsigned char, 2>::New());
  else
    write(itk::Image<itk::RGBPixel<unsigned char>, 2>::New());
}

}  // namespace ms::io
