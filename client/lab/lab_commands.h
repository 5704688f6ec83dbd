// The lab's commands (`invr-lab bench ...`, `invr-lab eval`): benchmarks and the speed-against-accuracy
// suite, registered on the CLI by client/main.cc. Each callback runs its command and sets `exitCode`.
#pragma once

#include <CLI/CLI.hpp>

namespace invr::cli {

void addBenchCommand(CLI::App& app, int& exitCode);  // bench rays, overhead, reconstruct, and the ones below
void addBenchGradientCommands(CLI::App& bench, int& exitCode);
void addBenchServiceCommand(CLI::App& bench, int& exitCode);
void addBenchFakeWorkerCommand(CLI::App& bench, int& exitCode);
void addBenchPixelCommand(CLI::App& bench, int& exitCode);
void addBenchVarianceCommand(CLI::App& bench, int& exitCode);
void addBenchSamplerCommand(CLI::App& bench, int& exitCode);  // bench sampler: independent against sobol
void addBenchStepCommand(CLI::App& bench, int& exitCode);     // bench step: a gradient step against its rays' Embree time
void addBenchScaleCommand(CLI::App& bench, int& exitCode);    // bench scale: step time and memory against problem size
void addBenchGradientVectorCommand(CLI::App& bench, int& exitCode);  // bench gradient-vector: a job's gradient with standard errors
void addBenchDerivativeImagesCommand(CLI::App& bench, int& exitCode);  // bench derivative-images: Wang et al.'s Fig. 6 measure
void addEvalCommand(CLI::App& app, int& exitCode);  // eval: the speed-against-accuracy suite

}  // namespace invr::cli
