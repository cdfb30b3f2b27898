#!/usr/bin/env bash
# A baked world served like map tiles (docs/embedding.md "Serving worlds"): nginx on 127.0.0.1 serves a copy
# of the world directory, and the world is streamed over HTTP range requests.
#   1. every cell loaded over HTTP is bit-identical to the disk's (lfgi_http_check same);
#   2. lfgi::Runtime with VIR visibility samples the same GI over HTTP as from disk (lfgi_http_check
#      runtime); `lfgi fly --world URL`, with the codec's relight and with --relight vir, flies over it
#      with no pixel missing GI;
#   3. the server stopped under an open world, in the middle of a cell's transfer: every load fails
#      naming the URL, the first mid-transfer, fallbacks stay (lfgi_http_check dropped), and a new flight
#      exits 1 naming the URL;
#   4. a region file served shorter than its index says: only the cut cell is corrupt, named.
# One nginx process (master_process off), so it serves as the user running the test: no worker switches
# to "nobody", which could not read a private (0700) temporary directory.
# Usage: http_serving.sh LFGI HTTP_CHECK BAKED_WORLD_DIR TMP_DIR
set -euo pipefail
lfgi="$1" check="$2" world="$3" tmp="$4"
nginx="$(command -v nginx || echo /usr/sbin/nginx)"
if [[ ! -x "$nginx" ]]; then
  echo "http_serving: nginx is not installed (scripts/apt-packages.txt lists nginx-light)" >&2
  exit 1
fi
rm -rf "$tmp"
mkdir -p "$tmp/logs" "$tmp/temp" "$tmp/www"
cp -r "$world" "$tmp/www/world"
stop() { [[ -f "$tmp/nginx.pid" ]] && kill "$(cat "$tmp/nginx.pid")" 2>/dev/null || true; rm -f "$tmp/nginx.pid"; }
trap stop EXIT

# nginx.conf for port $1; with $2 = slow, a cell's byte range (a Range not starting at 0: not a region
# head) is sent at 64 B/s, so a server stopped during it drops the connection mid-transfer.
conf() {
  local port="$1" map="" limit=""
  if [[ "${2:-}" == slow ]]; then
    map='map $http_range $cell_rate { "" 0; "~^bytes=0-" 0; default 64; }'
    limit='limit_rate $cell_rate;'
  fi
  cat <<CONF
worker_processes 1;
master_process off;
daemon on;
pid $tmp/nginx.pid;
error_log $tmp/logs/error.log;
events { worker_connections 64; }
http {
  access_log $tmp/logs/access.log;
  client_body_temp_path $tmp/temp/body;
  proxy_temp_path $tmp/temp/proxy;
  fastcgi_temp_path $tmp/temp/fastcgi;
  default_type application/octet-stream;
  $map
  server { listen 127.0.0.1:$port; root $tmp/www; $limit }
}
CONF
}

# A free port: try a few, nginx refuses to start on a taken one.
start() {
  local port
  for i in $(seq 0 19); do
    port=$(( 20000 + ($$ * 7 + i * 131) % 40000 ))
    conf "$port" > "$tmp/nginx.conf"
    if "$nginx" -p "$tmp" -c "$tmp/nginx.conf" -e "$tmp/logs/error.log" 2>>"$tmp/logs/start.log"; then
      for _ in $(seq 1 50); do [[ -s "$tmp/nginx.pid" ]] && break; sleep 0.1; done
      echo "$port"
      return 0
    fi
  done
  cat "$tmp/logs/start.log" >&2
  return 1
}

port=$(start)
url="http://127.0.0.1:$port/world"
echo "http_serving: nginx $("$nginx" -v 2>&1 | sed 's/.*\///') on $url"
"$check" same "$world" "$url"
"$check" runtime "$world" "$url"
out=$("$lfgi" fly --world "$url" --relight vir --seconds 1 --out "$tmp/fly_vir" 2>&1) || { echo "$out"; exit 1; }
echo "$out" | grep -E ", 0 with missing GI" >/dev/null ||
  { echo "$out"; echo "http_serving: the VIR flight over HTTP has pixels missing GI" >&2; exit 1; }
out=$("$lfgi" fly --world "$url" --seconds 2 --out "$tmp/fly" 2>&1) || { echo "$out"; exit 1; }
echo "$out" | grep -E "^source: regions from $url/baked/regions \(4 valid, 0 missing, 0 corrupt" >/dev/null ||
  { echo "$out"; echo "http_serving: the flight did not stream the served regions" >&2; exit 1; }
echo "$out" | grep -E ", 0 with missing GI" >/dev/null || { echo "$out"; echo "http_serving: pixels missing GI" >&2; exit 1; }
echo "fly: $(echo "$out" | grep -m1 '^source:')"
grep -q '" 206 ' "$tmp/logs/access.log" || { echo "http_serving: no range request (206) in the access log" >&2; exit 1; }
echo "range requests answered 206: $(grep -c '" 206 ' "$tmp/logs/access.log")"

# A region file cut short: the last record of the region (cell 1,1 in z-then-x order) is truncated.
region=$(ls "$tmp/www/world/baked/regions/"*.lfgr | head -1)
truncate -s -64 "$region"
"$check" truncated "$url" 1,1
cp "$world/baked/regions/$(basename "$region")" "$region"

# Under the open world, the server is swapped for a slow one and stopped 1 s into the first cell's
# transfer: that load fails mid-transfer, the rest find no server; every error names the URL.
conf "$port" slow > "$tmp/nginx_slow.conf"
swap="kill \$(cat '$tmp/nginx.pid'); sleep 0.5; '$nginx' -p '$tmp' -c '$tmp/nginx_slow.conf' -e '$tmp/logs/error.log'"
swap+=" || exit 1; sleep 0.3; (sleep 1; kill \$(cat '$tmp/nginx.pid')) &"
out=$("$check" dropped "$url" "$swap") || { echo "$out"; exit 1; }
echo "$out"
echo "$out" | grep -q "the first: .*Couldn't connect" &&
  { echo "http_serving: the first load did not fail mid-transfer" >&2; exit 1; }
sleep 1.5
rm -f "$tmp/nginx.pid"
if "$lfgi" fly --world "$url" --seconds 1 --out "$tmp/fly_down" >"$tmp/down.log" 2>&1; then
  echo "http_serving: a flight with the server down succeeded" >&2
  exit 1
fi
grep -E "lfgi: error: $url/world.json: " "$tmp/down.log" ||
  { cat "$tmp/down.log"; echo "http_serving: the error does not name the URL" >&2; exit 1; }
echo "http_serving: ok"
