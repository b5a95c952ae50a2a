// The login page: sends the account and password as JSON, and shows the page once logged in.
'use strict';
(() => {
  const form = document.getElementById('login-form');
  const reply = document.getElementById('login-reply');
  form.addEventListener('submit', async (e) => {
    e.preventDefault();
    reply.textContent = 'logging in…';
    try {
      const r = await fetch('/api/login', {
        method: 'POST',
        headers: { 'Content-Type': 'application/json' },
        body: JSON.stringify({
          account: document.getElementById('account').value,
          password: document.getElementById('password').value,
        }),
      });
      const j = await r.json();
      if (j.ok) { window.location.assign('/'); return; }
      reply.textContent = j.error ? j.error.message : `HTTP ${r.status}`;
    } catch (err) {
      reply.textContent = `cannot log in: ${err}`;
    }
  });
})();
