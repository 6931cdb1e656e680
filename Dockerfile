# Reproduces the project's set-up on Debian bookworm with the same script as every machine.
FROM debian:bookworm
ENV DEBIAN_FRONTEND=noninteractive OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
RUN apt-get update -qq && apt-get install -y -qq --no-install-recommends make ca-certificates && rm -rf /var/lib/apt/lists/*
WORKDIR /app
COPY . .
RUN bash scripts/setup.sh
CMD ["make", "run"]
