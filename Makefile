# Two entry points, each doing all set-up a fresh Debian machine needs:
#   make demo   — builds icefem and runs the paper's scene with fracture,
#                 scenes/freezing_container_fracture.toml, to freezing_container_fracture.h5
#                 (+ .xdmf, .cracks.xdmf), then draws the paper's figure from it
#                 (freezing_container_fracture_figure.png)
#   make test   — runs the whole test suite (cargo test --release), then reads icefem's files
#                 with readers that are not icefem's (validation/check_readers.sh: the Python
#                 reader's tests, the XDMF through VTK, the exports through pxr.Usd, meshio, VTK),
#                 then runs docs/first_scene.md as written (validation/first_scene.py) and opens
#                 USD exports in Blender (validation/blender_import.py); it installs Gmsh first
#                 (make gmsh), which `icefem mesh` and that page use, and Blender's bpy wheel
#                 (make blender)
# and, for runs on several processes (the `mpi` feature):
#   make mpi      — installs OpenMPI, PETSc, parallel HDF5 and libclang (apt-get), builds
#                   target/release/icefem with the feature: `mpirun -n N target/release/icefem run SCENE`
#   make test-mpi — the distributed tests (2, 3 and 4 processes against 1), the partition
#                   on 3 processes, and the scikit-fem validation on 2 processes
# The only system library the build needs is HDF5 (libhdf5-dev), installed with apt-get when
# missing; the readers' Python venv (wheels only) is created in target/readers-venv, and
# Gmsh's (the gmsh wheel, with the X and GL libraries it links, apt-get) in target/gmsh-venv,
# Blender's (the bpy wheel) in target/blender-venv.

SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: deps gmsh blender demo test figures mpi-deps mpi test-mpi

deps:
	@pkg-config --exists hdf5 2>/dev/null || { \
		echo "installing libhdf5-dev (HDF5 C library for the hdf5-metno crate)"; \
		$(SUDO) apt-get update -qq && $(SUDO) DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libhdf5-dev pkg-config; }

# Gmsh for `icefem mesh` (and the walkthrough of docs/first_scene.md): the gmsh wheel in its
# own venv, target/gmsh-venv, where `icefem mesh` finds it (target/gmsh-venv/bin/gmsh).
GMSH_VENV := target/gmsh-venv
GMSH_LIBS := libglu1-mesa libgl1 libxrender1 libxcursor1 libxfixes3 libxext6 libxft2 libfontconfig1 libxinerama1 libx11-6 libgomp1
gmsh: $(GMSH_VENV)/.installed
$(GMSH_VENV)/.installed: validation/requirements-gmsh.txt
	@python3 -c "import ensurepip, venv" 2>/dev/null || { \
		echo "installing python3-venv"; \
		$(SUDO) apt-get update -qq && $(SUDO) DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv; }
	rm -rf $(GMSH_VENV)
	python3 -m venv $(GMSH_VENV)
	$(GMSH_VENV)/bin/python -m pip install --quiet --only-binary=:all: -r validation/requirements-gmsh.txt
	@$(GMSH_VENV)/bin/python -c "import gmsh" 2>/dev/null || { \
		echo "installing $(GMSH_LIBS) (the libraries the gmsh wheel links)"; \
		$(SUDO) apt-get update -qq && $(SUDO) DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(GMSH_LIBS); }
	$(GMSH_VENV)/bin/python -c "import gmsh"
	touch $@

# Blender as a Python module (the bpy wheel, Python 3.11 only) in target/blender-venv, for
# validation/blender_import.py; on another Python the venv is not made and the check is skipped.
BLENDER_VENV := target/blender-venv
blender: $(BLENDER_VENV)/.installed
$(BLENDER_VENV)/.installed: validation/requirements-blender.txt
	@if python3 -c "import sys; sys.exit(sys.version_info[:2] != (3, 11))"; then \
		rm -rf $(BLENDER_VENV) && python3 -m venv $(BLENDER_VENV) && \
		$(BLENDER_VENV)/bin/python -m pip install --quiet --only-binary=:all: -r validation/requirements-blender.txt && \
		$(BLENDER_VENV)/bin/python -c "import bpy" && touch $@; \
	else echo "python3 is not 3.11: no bpy wheel, the Blender check is skipped"; fi

# PETSc 3.18 (with hypre), OpenMPI 4.1 and HDF5 built for MPI from Debian; libclang for
# bindgen, which generates the PETSc declarations at build time.
MPI_PACKAGES := libopenmpi-dev openmpi-bin libpetsc-real-dev libhdf5-openmpi-dev libclang-dev pkg-config
mpi-deps:
	@dpkg -s $(MPI_PACKAGES) >/dev/null 2>&1 || { \
		echo "installing $(MPI_PACKAGES)"; \
		$(SUDO) apt-get update -qq && $(SUDO) DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(MPI_PACKAGES); }

mpi: mpi-deps
	cargo build --release --features mpi

# Processes as root (CI containers) need OpenMPI's consent; more processes than cores, too.
MPIRUN := mpirun --oversubscribe --allow-run-as-root
test-mpi: mpi-deps
	cargo test --release --features mpi --test distributed --test partition
	$(MPIRUN) -n 2 $$(cargo test --release --features mpi --test validation --no-run 2>&1 \
		| sed -n 's/.*Executable .*(\(.*validation-[0-9a-f]*\)).*/\1/p') --test-threads=1

demo: deps
	cargo run --release -- run scenes/freezing_container_fracture.toml --output freezing_container_fracture.h5 --force
	cargo run --release -- figure freezing_container_fracture.h5

# The README's figures (docs/*.png) from the paper's scene without and with fracture and
# frozen by conduction (~30 s).
FIG := target/figures
figures: deps gmsh blender
	cargo build --release
	$(GMSH_VENV)/bin/python validation/first_scene.py --keep $(FIG)/first_scene
	./target/release/icefem figure $(FIG)/first_scene/glass_of_water.h5 --size 1650x476 --output docs/first_scene_figure.png
	mkdir -p $(FIG) docs
	./target/release/icefem run scenes/freezing_container.toml --output $(FIG)/freezing_container.h5 --force
	./target/release/icefem figure $(FIG)/freezing_container.h5 --size 1800x476 --cut y=0.05 --color-by freeze --style solid --output docs/freezing_container_figure.png
	./target/release/icefem run scenes/freezing_container_fracture.toml --output $(FIG)/freezing_container_fracture.h5 --force
	./target/release/icefem figure $(FIG)/freezing_container_fracture.h5 --size 1650x476 --output docs/freezing_container_fracture_figure.png
	./target/release/icefem figure $(FIG)/freezing_container_fracture.h5 --size 1800x476 --cut y=0.05 --color-by plastic --style solid --output docs/freezing_container_fracture_plastic.png
	./target/release/icefem -q export $(FIG)/freezing_container_fracture.h5 --format usd --force --output $(FIG)/freezing_container_fracture.usda
	$(BLENDER_VENV)/bin/python python/blender/icefem_blender.py $(FIG)/freezing_container_fracture.usda --render docs/export_blender.png --size 640x480 --samples 64
	./target/release/icefem run scenes/freezing_container_thermal.toml --output $(FIG)/freezing_container_thermal.h5 --force
	./target/release/icefem figure $(FIG)/freezing_container_thermal.h5 --size 1800x476 --frames 0,12,23,96 --cut y=0.05 --color-by temperature --style solid --output docs/freezing_container_thermal_figure.png

test: deps gmsh blender
	cargo test --release
	validation/check_readers.sh
	$(GMSH_VENV)/bin/python validation/first_scene.py
	@if [ -x $(BLENDER_VENV)/bin/python ]; then $(BLENDER_VENV)/bin/python validation/blender_import.py; \
	else echo "skipped validation/blender_import.py: the bpy wheel needs Python 3.11"; fi
