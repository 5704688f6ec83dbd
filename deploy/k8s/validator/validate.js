#!/usr/bin/env node
// Validates Kubernetes objects (multi-document YAML, from files or stdin: the output of
// `kubectl kustomize deploy/k8s`) against the Kubernetes API schema, offline: each object's
// apiVersion and kind select the model of the kubernetes-models package (generated from the
// Kubernetes OpenAPI schema), whose validator checks types, required fields, enums and formats.
// Prints one line per object; exits 1 if any object is invalid or of an unknown kind.
"use strict";
const fs = require("fs");
const YAML = require("yaml");

function modelFor(apiVersion, kind) {
  const [group, version] = apiVersion.includes("/") ? apiVersion.split("/") : [null, apiVersion];
  const path = group ? `kubernetes-models/${group}/${version}/${kind}` : `kubernetes-models/${version}/${kind}`;
  try {
    const mod = require(path);
    return mod[kind];
  } catch (e) {
    return null;
  }
}

const inputs = process.argv.slice(2);
const text = inputs.length ? inputs.map((f) => fs.readFileSync(f, "utf8")).join("\n---\n") : fs.readFileSync(0, "utf8");
let bad = 0, count = 0;
for (const doc of YAML.parseAllDocuments(text)) {
  if (doc.errors.length) {
    console.log(`YAML error: ${doc.errors[0].message}`);
    bad++;
    continue;
  }
  const obj = doc.toJSON();
  if (obj === null || obj === undefined) continue;
  count++;
  const name = `${obj.kind || "?"}/${(obj.metadata && obj.metadata.name) || "?"}`;
  if (!obj.apiVersion || !obj.kind) {
    console.log(`INVALID ${name}: no apiVersion or kind`);
    bad++;
    continue;
  }
  const Model = modelFor(obj.apiVersion, obj.kind);
  if (!Model) {
    console.log(`INVALID ${name}: no schema for ${obj.apiVersion} ${obj.kind}`);
    bad++;
    continue;
  }
  try {
    new Model(obj).validate();
    console.log(`ok ${obj.apiVersion} ${name}`);
  } catch (e) {
    console.log(`INVALID ${obj.apiVersion} ${name}: ${e.message}`);
    bad++;
  }
}
if (count === 0) {
  console.log("no objects to validate");
  process.exit(1);
}
console.log(`${count - bad}/${count} objects valid`);
process.exit(bad ? 1 : 0);
