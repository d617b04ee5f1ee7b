# Two entry points, each doing all set-up a fresh Debian machine needs:
#   make demo   — builds icefem and runs the paper's scene with fracture,
#                 scenes/freezing_container_fracture.toml, to freezing_container_fracture.h5
#                 (+ .xdmf, .cracks.xdmf), then draws the paper's figure from it
#                 (freezing_container_fracture_figure.png)
#   make test   — runs the whole test suite (cargo test --release), then reads icefem's files
#                 with readers that are not icefem's (validation/check_readers.sh: the Python
#                 reader's tests, the XDMF through VTK, the exports through pxr.Usd, meshio, VTK)
# The only system library needed is HDF5 (libhdf5-dev), installed with apt-get when missing;
# the readers' Python venv (wheels only) is created in target/readers-venv.

SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: deps demo test figures

deps:
	@pkg-config --exists hdf5 2>/dev/null || { \
		echo "installing libhdf5-dev (HDF5 C library for the hdf5-metno crate)"; \
		$(SUDO) apt-get update -qq && $(SUDO) DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libhdf5-dev pkg-config; }

demo: deps
	cargo run --release -- run scenes/freezing_container_fracture.toml --output freezing_container_fracture.h5 --force
	cargo run --release -- figure freezing_container_fracture.h5

# The README's figures (docs/*.png) from the paper's scene without and with fracture and
# frozen by conduction (~30 s).
FIG := target/figures
figures: deps
	cargo build --release
	mkdir -p $(FIG) docs
	./target/release/icefem run scenes/freezing_container.toml --output $(FIG)/freezing_container.h5 --force
	./target/release/icefem figure $(FIG)/freezing_container.h5 --size 400x400 --cut y=0.05 --color-by freeze --style solid --output docs/freezing_container_figure.png
	./target/release/icefem run scenes/freezing_container_fracture.toml --output $(FIG)/freezing_container_fracture.h5 --force
	./target/release/icefem figure $(FIG)/freezing_container_fracture.h5 --size 400x400 --output docs/freezing_container_fracture_figure.png
	./target/release/icefem figure $(FIG)/freezing_container_fracture.h5 --size 400x400 --cut y=0.05 --color-by plastic --style solid --output docs/freezing_container_fracture_plastic.png
	./target/release/icefem run scenes/freezing_container_thermal.toml --output $(FIG)/freezing_container_thermal.h5 --force
	./target/release/icefem figure $(FIG)/freezing_container_thermal.h5 --size 400x400 --frames 0,12,23,96 --cut y=0.05 --color-by temperature --style solid --output docs/freezing_container_thermal_figure.png

test: deps
	cargo test --release
	validation/check_readers.sh
