#!/usr/bin/env bash
# The deploy/ nginx config on loopback in front of two `linecloud serve`
# processes: client-feature requests from 4 parallel clients, one server
# killed with -9 mid-load; every request must still be answered 200 (nginx
# retries on the other server). Then a short wrk run through nginx (bounded:
# 10 s, 8 connections), and the hostile rows through nginx (scripts/nginx_hostile.py). Needs the fountain-P11 work of `eval prepare`
# (LINECLOUD_FOUNTAIN_WORK, default build/eval/fountain-P11), nginx and wrk.
set -euo pipefail
cd "$(dirname "$0")/.."
work="${LINECLOUD_FOUNTAIN_WORK:-build/eval/fountain-P11}"
photo="$(bash scripts/data_dir.sh)/strecha/fountain-P11/images/0000.jpg"
camera="PINHOLE 1536 1024 1379.74 1382.08 760.095 503.155"
if [ ! -f "$work/prepared.json" ] || [ ! -f "$photo" ]; then
  # Under the test command (LINECLOUD_REQUIRE_ALL=1) a part that cannot run is a failure.
  if [ "${LINECLOUD_REQUIRE_ALL:-}" = 1 ]; then
    echo "fault test FAILED: no fountain-P11 work at $work (eval prepare) or no $photo"; exit 1
  fi
  echo "fault test skipped: no fountain-P11 work at $work (run eval prepare) or no $photo"
  exit 0
fi
tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  [ -f "$tmp/nginx.pid" ] && kill "$(cat "$tmp/nginx.pid")" 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT
mkdir -p "$tmp/maps" "$tmp/logs"
LINECLOUD_KEY_STORE="$tmp/keys" ./build/linecloud lift --model "$work/groups/g00/map" \
  --database "$work/colmap/database.db" --out "$tmp/maps/fountain.lcm" > /dev/null 2>&1
./build/linecloud features --image "$photo" --camera "$camera" --out "$tmp/body.json"

ports=()
for k in 1 2; do
  ./build/linecloud serve --maps "$tmp/maps" --listen 127.0.0.1:0 --threads 1 --queue 32 \
    > /dev/null 2> "$tmp/serve$k.log" &
  pids+=($!)
done
for k in 1 2; do
  for _ in $(seq 100); do
    port=$(sed -n 's|.*listening on http://127.0.0.1:\([0-9]*\).*|\1|p' "$tmp/serve$k.log")
    [ -n "$port" ] && break
    sleep 0.1
  done
  [ -n "$port" ] || { cat "$tmp/serve$k.log"; exit 1; }
  ports+=("$port")
done
# A free loopback port for nginx: nothing answers a connection to it.
front=""
for _ in $(seq 50); do
  p=$((20000 + RANDOM % 40000))
  if ! (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; then front=$p; break; fi
done
[ -n "$front" ] || { echo "fault test: no free port found"; exit 1; }
# deploy/nginx.conf with these ports, its pid and logs in the scratch folder.
sed -e "s|server 127.0.0.1:8081|server 127.0.0.1:${ports[0]}|" \
    -e "s|server 127.0.0.1:8082|server 127.0.0.1:${ports[1]}|" \
    -e "s|listen 127.0.0.1:8080|listen 127.0.0.1:$front|" \
    -e "s|^pid .*|pid $tmp/nginx.pid;|" \
    -e "s|^error_log .*|error_log $tmp/logs/error.log warn;|" \
    -e "s|http {|http {\n  client_body_temp_path $tmp/body; proxy_temp_path $tmp/proxy;|" \
    deploy/nginx.conf > "$tmp/nginx.conf"
nginx -p "$tmp" -c "$tmp/nginx.conf" -g "user $(id -un);"
for _ in $(seq 50); do [ -f "$tmp/nginx.pid" ] && break; sleep 0.1; done
url="http://127.0.0.1:$front/v1/maps/fountain/localize"

# 4 clients x 15 requests; the server that owns the map killed after the 5th answer.
client() {
  for _ in $(seq 15); do
    curl -s -o /dev/null -w '%{http_code}\n' -H 'Content-Type: application/json' \
      --data-binary @"$tmp/body.json" "$url" >> "$tmp/codes$1"
  done
}
for c in 1 2 3 4; do client "$c" & done
for _ in $(seq 600); do
  [ "$(cat "$tmp"/codes* 2>/dev/null | wc -l)" -ge 5 ] && break
  sleep 0.05
done
victim=""
for k in 0 1; do
  if grep -q '"route":"/v1/maps/{id}/localize"' "$tmp/serve$((k + 1)).log"; then victim=$k; fi
done
[ -n "$victim" ] || victim=0
kill -9 "${pids[$victim]}"
echo "killed server $((victim + 1)) (port ${ports[$victim]}) with -9 after $(cat "$tmp"/codes* | wc -l) answers"
wait $(jobs -p | grep -v -e "${pids[0]}" -e "${pids[1]}") 2>/dev/null || true
total=$(cat "$tmp"/codes* | wc -l)
ok=$(grep -c '^200$' <(cat "$tmp"/codes*) || true)
echo "fault test: $ok of $total requests answered 200 (60 sent; one of two servers killed mid-load)"
[ "$total" -eq 60 ] && [ "$ok" -eq 60 ] || { sort "$tmp"/codes* | uniq -c; exit 1; }

# A bounded wrk run through nginx on the survivor.
cat > "$tmp/post.lua" <<LUA
wrk.method = "POST"
wrk.headers["Content-Type"] = "application/json"
local f = io.open("$tmp/body.json", "rb"); wrk.body = f:read("*a"); f:close()
LUA
wrk -t2 -c8 -d10s --latency -s "$tmp/post.lua" "$url" | sed -n '1,20p'

# Issue [shield]'s hostile rows again through nginx (on the survivor).
/usr/bin/python3 scripts/nginx_hostile.py "$front" fountain "$tmp/body.json"
