# Multi-stage build of the same `millsim` binary; SQLite lives on a volume.
FROM rust:1-bookworm AS build
WORKDIR /src
COPY . .
RUN cargo build --release --locked --bin millsim

FROM debian:bookworm-slim
RUN useradd --system --uid 10001 --home /var/lib/millsim --create-home millsim
COPY --from=build /src/target/release/millsim /usr/local/bin/millsim
USER millsim
WORKDIR /var/lib/millsim
VOLUME ["/var/lib/millsim"]
ENV MILLSIM_BIND=0.0.0.0:8080 \
    MILLSIM_DATABASE=sqlite:///var/lib/millsim/millsim.db
EXPOSE 8080
# A non-loopback bind needs API keys: mount a key file and set MILLSIM_API_KEY_FILE.
ENTRYPOINT ["millsim"]
CMD ["serve"]
