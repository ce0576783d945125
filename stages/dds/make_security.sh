#!/usr/bin/env bash
# Makes what DDS Security needs for one pipeline (stages/dds/README.md, "Security"): a CA, the
# signed governance of the pipeline's domain, and three identities, each a folder for
# `gcpipe ... --identity FOLDER` (or `identity:` in a pipeline file, for the nodes):
#
#   node     the pipeline's stages and sinks: publish and subscribe every gcpipe_* topic
#   feeder   who may put programs into the pipeline: publish gcpipe_program (and its monitor copy)
#   monitor  who may watch it: subscribe the keep-last copies (*_monitor) only, publish nothing
#
#   bash stages/dds/make_security.sh OUT_DIR DOMAIN [DAYS]
#
# Governance (one domain): no unauthenticated participant is matched; discovery, liveliness and
# every gcpipe_* topic's data and metadata are encrypted (AES-GCM), reading and writing are
# access-controlled. Keys are ECDSA P-256, certificates valid DAYS (default 3650). The CA's key
# stays in OUT_DIR/ca (copy only the identity folders to the hosts). Run again to make new
# identities with the same CA; uses openssl only.
set -euo pipefail
set -f  # topic patterns such as gcpipe_* are text here, never file names

if [ $# -lt 2 ] || [ $# -gt 3 ]; then
  echo "usage: bash $0 OUT_DIR DOMAIN [DAYS]" >&2
  exit 2
fi
out="$1"
domain="$2"
days="${3:-3650}"
if ! [[ "$domain" =~ ^[0-9]+$ ]] || [ "$domain" -gt 232 ]; then
  echo "make_security.sh: DOMAIN '$domain' is not a DDS domain id (an integer in [0, 232])" >&2
  exit 2
fi
if ! [[ "$days" =~ ^[1-9][0-9]*$ ]]; then
  echo "make_security.sh: DAYS '$days' is not a positive whole number" >&2
  exit 2
fi
command -v openssl >/dev/null || { echo "make_security.sh: needs openssl (apt-get install openssl)" >&2; exit 1; }

mkdir -p "$out/ca"
ca_key="$out/ca/ca.key.pem"
ca_cert="$out/ca/ca.cert.pem"
umask 077

make_ca() {
  [ -f "$ca_key" ] && [ -f "$ca_cert" ] && return
  openssl ecparam -name prime256v1 -genkey -noout -out "$ca_key"
  openssl req -new -x509 -sha256 -key "$ca_key" -out "$ca_cert" -days "$days" \
    -subj "/O=gcpipe/CN=gcpipe pipeline CA" -addext "basicConstraints=critical,CA:TRUE" \
    -addext "keyUsage=critical,keyCertSign,cRLSign,digitalSignature"
}

sign() {  # sign IN.xml OUT.p7s: S/MIME as the DDS Security builtin plugins read it
  openssl smime -sign -in "$1" -text -out "$2" -signer "$ca_cert" -inkey "$ca_key"
}

write_governance() {
  cat > "$out/ca/governance.xml" <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains><id>$domain</id></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>NONE</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>gcpipe_*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
EOF
  sign "$out/ca/governance.xml" "$out/ca/governance.p7s"
}

topics() { for t in "$@"; do echo "          <topic>$t</topic>"; done; }

# identity NAME "PUBLISH TOPICS" "SUBSCRIBE TOPICS"
identity() {
  local name="$1" dir="$out/$1" subject="CN=gcpipe $1,O=gcpipe"
  mkdir -p "$dir"
  openssl ecparam -name prime256v1 -genkey -noout -out "$dir/key.pem"
  openssl req -new -sha256 -key "$dir/key.pem" -out "$dir/cert.csr" -subj "/O=gcpipe/CN=gcpipe $name"
  openssl x509 -req -sha256 -in "$dir/cert.csr" -CA "$ca_cert" -CAkey "$ca_key" -CAcreateserial \
    -out "$dir/cert.pem" -days "$days" 2>/dev/null
  rm -f "$dir/cert.csr"
  local rules=""
  [ -n "$2" ] && rules+="        <publish><topics>
$(topics $2)
        </topics></publish>
"
  [ -n "$3" ] && rules+="        <subscribe><topics>
$(topics $3)
        </topics></subscribe>
"
  cat > "$dir/permissions.xml" <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd">
  <permissions>
    <grant name="gcpipe_$name">
      <subject_name>$subject</subject_name>
      <validity>
        <not_before>$(date -u -d "-1 day" +%Y-%m-%dT%H:%M:%S)</not_before>
        <not_after>$(date -u -d "+$days days" +%Y-%m-%dT%H:%M:%S)</not_after>
      </validity>
      <allow_rule>
        <domains><id>$domain</id></domains>
$rules      </allow_rule>
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
EOF
  sign "$dir/permissions.xml" "$dir/permissions.p7s"
  cp "$ca_cert" "$dir/identity_ca.pem"
  cp "$ca_cert" "$dir/permissions_ca.pem"
  cp "$out/ca/governance.p7s" "$dir/governance.p7s"
  echo "identity $name: $dir ($subject; publishes: ${2:-nothing}; subscribes: ${3:-nothing})"
}

make_ca
write_governance
identity node "gcpipe_*" "gcpipe_*"
identity feeder "gcpipe_program gcpipe_program_monitor gcpipe_program_heartbeat" ""
identity monitor "" "gcpipe_*_monitor"
echo "CA: $ca_cert (its key $ca_key stays here); governance: domain $domain"
