#!/usr/bin/env bash
# Makes the farm's secrets: random bearer tokens for the four roles and, with --tls, a
# test certificate authority and a server certificate signed by it.
#
#   bash deploy/make-secrets.sh [--dir DIR] [--tls NAME[,NAME...]] [--worker NAME]... [--days N] [--force]
#
# Writes into DIR (default deploy/secrets/, which git ignores):
#   tokens        the coordinator's --tokens file: lines "ROLE TOKEN" (client, worker, admin,
#                 metrics: what Prometheus presents to the coordinator's and workers' metrics)
#   worker.env    CPVS_TOKEN=<worker token>, for docker compose's env_file
#   client.token  worker.token  admin.token  metrics.token   one token each
#   with --tls:   ca.crt ca.key tls.crt tls.key  (the server certificate names every NAME:
#                 DNS names, or IP addresses when NAME is one; coordinator, cpvs-coordinator
#                 and localhost/127.0.0.1 are always added)
#   with --worker NAME: worker-NAME.crt worker-NAME.key, a client certificate signed by the
#                 same CA (the CA must exist: --tls now or before): a worker that presents it
#                 to a coordinator with --worker-ca ca.crt needs no token (its name: NAME)
#
# Existing files are kept unless --force. The directory is made 0700; the files in it are
# 0644 so that the containers' non-root user can read them through compose's bind mounts
# (nobody else on the host can reach them through the 0700 directory). ca.key stays 0600.
set -euo pipefail

dir="$(cd "$(dirname "$0")" && pwd)/secrets"
tls_names=""
workers=()
days=365
force=0

usage() { sed -n '2,21p' "$0" | sed 's/^# \{0,1\}//'; }

while [ $# -gt 0 ]; do
  case "$1" in
    --dir) dir="${2:?--dir needs a directory}"; shift 2 ;;
    --tls) tls_names="${2:?--tls needs NAME[,NAME...]}"; shift 2 ;;
    --worker) workers+=("${2:?--worker needs a NAME}"); shift 2 ;;
    --days) days="${2:?--days needs a number}"; shift 2 ;;
    --force) force=1; shift ;;
    -h|--help) usage; exit 0 ;;
    *) echo "make-secrets: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done

mkdir -p "$dir"
chmod 0700 "$dir"

token() { head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \n'; }

writable() {  # writable FILE: true when FILE may be (re)written
  if [ -e "$1" ] && [ "$force" -eq 0 ]; then
    echo "make-secrets: keeping existing $1 (--force to replace)"
    return 1
  fi
  return 0
}

if writable "$dir/tokens"; then
  client="$(token)"; worker="$(token)"; admin="$(token)"; metrics="$(token)"
  umask 077
  printf 'client %s\nworker %s\nadmin %s\nmetrics %s\n' "$client" "$worker" "$admin" "$metrics" >"$dir/tokens"
  printf 'CPVS_TOKEN=%s\n' "$worker" >"$dir/worker.env"
  printf '%s\n' "$client" >"$dir/client.token"
  printf '%s\n' "$worker" >"$dir/worker.token"
  printf '%s\n' "$admin" >"$dir/admin.token"
  printf '%s\n' "$metrics" >"$dir/metrics.token"
  chmod 0644 "$dir/tokens" "$dir/worker.env" "$dir/client.token" "$dir/worker.token" "$dir/admin.token" \
    "$dir/metrics.token"
  echo "make-secrets: wrote $dir/tokens, worker.env, client.token, worker.token, admin.token, metrics.token"
fi

if [ -n "$tls_names" ]; then
  command -v openssl >/dev/null || { echo "make-secrets: --tls needs openssl" >&2; exit 2; }
  if writable "$dir/tls.crt"; then
    san="DNS:coordinator,DNS:cpvs-coordinator,DNS:localhost,IP:127.0.0.1"
    IFS=',' read -r -a names <<<"$tls_names"
    for n in "${names[@]}"; do
      [ -n "$n" ] || continue
      if [[ "$n" =~ ^[0-9.]+$ || "$n" == *:* ]]; then san="$san,IP:$n"; else san="$san,DNS:$n"; fi
    done
    tmp="$(mktemp -d)"
    trap 'rm -rf "$tmp"' EXIT
    umask 077
    openssl req -x509 -newkey rsa:3072 -nodes -days "$days" -subj "/CN=cpvs test CA" \
      -keyout "$dir/ca.key" -out "$dir/ca.crt" \
      -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
      2>/dev/null
    openssl req -newkey rsa:3072 -nodes -subj "/CN=${names[0]:-coordinator}" \
      -keyout "$dir/tls.key" -out "$tmp/tls.csr" 2>/dev/null
    printf 'subjectAltName=%s\nbasicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature,keyEncipherment\nextendedKeyUsage=serverAuth\n' \
      "$san" >"$tmp/ext.cnf"
    openssl x509 -req -in "$tmp/tls.csr" -CA "$dir/ca.crt" -CAkey "$dir/ca.key" -CAcreateserial \
      -days "$days" -extfile "$tmp/ext.cnf" -out "$dir/tls.crt" 2>/dev/null
    rm -f "$dir/ca.srl"
    chmod 0644 "$dir/ca.crt" "$dir/tls.crt" "$dir/tls.key"
    chmod 0600 "$dir/ca.key"
    openssl verify -CAfile "$dir/ca.crt" "$dir/tls.crt" >/dev/null
    echo "make-secrets: wrote $dir/ca.crt, tls.crt, tls.key (names: $san), valid $days days"
  fi
fi

for w in "${workers[@]}"; do
  [[ "$w" =~ ^[A-Za-z0-9._-]{1,64}$ ]] || { echo "make-secrets: a worker name is 1-64 of A-Z a-z 0-9 . _ -" >&2; exit 2; }
  [ -f "$dir/ca.key" ] || { echo "make-secrets: --worker needs the CA: give --tls too (or run with it first)" >&2; exit 2; }
  if writable "$dir/worker-$w.crt"; then
    tmp="$(mktemp -d)"
    umask 077
    openssl req -newkey rsa:3072 -nodes -subj "/CN=$w" -keyout "$dir/worker-$w.key" -out "$tmp/w.csr" 2>/dev/null
    printf 'basicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature,keyEncipherment\nextendedKeyUsage=clientAuth\n' \
      >"$tmp/ext.cnf"
    openssl x509 -req -in "$tmp/w.csr" -CA "$dir/ca.crt" -CAkey "$dir/ca.key" -CAcreateserial -days "$days" \
      -extfile "$tmp/ext.cnf" -out "$dir/worker-$w.crt" 2>/dev/null
    rm -rf "$tmp" "$dir/ca.srl"
    chmod 0644 "$dir/worker-$w.crt" "$dir/worker-$w.key"
    openssl verify -CAfile "$dir/ca.crt" "$dir/worker-$w.crt" >/dev/null
    echo "make-secrets: wrote $dir/worker-$w.crt, worker-$w.key (a client certificate for worker $w)"
  fi
done
