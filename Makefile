# Convenience wrapper: everything goes through ./build.sh, which also installs
# missing build dependencies on Debian.
.PHONY: all build test demo bench clean
all: build
build:
	./build.sh build
test:
	./build.sh test
demo:
	./build.sh demo
bench:
	./build.sh bench
clean:
	./build.sh clean
