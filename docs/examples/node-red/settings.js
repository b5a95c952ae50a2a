// Node-RED settings for running the Cetratus MCT flow headless (README.md beside this file).
module.exports = {
    // Loopback only: the endpoints have no login.
    uiHost: "127.0.0.1",
    // No editor and no admin API: the flow is the file named on the command line, and nothing
    // can deploy another one over it.
    httpAdminRoot: false,
    // Request bodies are a few bytes: {"package": "u1.cpkg"}.
    apiMaxLength: "64kb",
    // Broker accounts, if any, are read from <userDir>/flow_cred.json, as plain JSON (README.md).
    credentialSecret: false,
    // The load function reads the package with Node's fs module.
    functionExternalModules: true,
    // Nothing is sent to nodered.org.
    telemetry: { enabled: false, updateNotification: false },
    diagnostics: { enabled: false },
    logging: { console: { level: "info", metrics: false, audit: false } },
};
