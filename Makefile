# Two entry points, each doing all set-up a fresh Debian machine needs:
#   make demo   — builds icefem and runs the paper's scene with fracture,
#                 scenes/freezing_container_fracture.toml, to freezing_container_fracture.h5
#                 (+ .xdmf, .cracks.xdmf)
#   make test   — runs the whole test suite (cargo test --release)
# The only system library needed is HDF5 (libhdf5-dev), installed with apt-get when missing.

SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: deps demo test bench

deps:
	@pkg-config --exists hdf5 2>/dev/null || { \
		echo "installing libhdf5-dev (HDF5 C library for the hdf5-metno crate)"; \
		$(SUDO) apt-get update -qq && $(SUDO) DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libhdf5-dev pkg-config; }

demo: deps
	cargo run --release -- run scenes/freezing_container_fracture.toml --output freezing_container_fracture.h5

test: deps
	cargo test --release
